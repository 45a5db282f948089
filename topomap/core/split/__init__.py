"""Phase 2, the paper's split: transition instances, the bottom-up merge, criteria, stopping rules."""
