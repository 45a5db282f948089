"""Doing one run: its data, the learner, the evaluation and the files it writes; one job of a
sweep, progress bars and interrupts."""
