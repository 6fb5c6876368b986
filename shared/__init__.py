"""The cores of the cell: pure mathematics and the vocabulary every process shares, one sub-package per
block of the architecture (no process is started from here)."""
