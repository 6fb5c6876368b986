"""The cores of the cell: pure mathematics and the vocabulary every process shares, one sub-package per
block of the architecture (no process is started from here). Importing it points numba's cache at this version
of the code (``shared.compiled``): compiled kernels of another version are never loaded."""

from shared.compiled import use_versioned_cache

use_versioned_cache()
