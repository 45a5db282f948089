"""The refinement after the split: EM over clones of the symbols, and structure moves."""
