"""The C library's allocator settings of a planning process (glibc's `mallopt`)."""

import ctypes

# mallopt's parameter numbers (glibc's malloc.h).
M_TRIM_THRESHOLD = -1
M_MMAP_THRESHOLD = -3

# Free memory at the top of the heap that glibc keeps rather than returns to the kernel, and the
# size from which a block is mapped on its own instead of taken from the heap. A plan at 50
# neighbours allocates arrays of 130 KB to a few MB and frees them before the next: with glibc's
# defaults (128 KiB each, raised only by what the process freed before) the next plan may fault
# those pages in again: about 1,000 minor faults and 1-3.5 ms per plan (docs/results.md, 5.8).
# 32 MiB is the largest mmap limit glibc's own adjustment reaches.
TRIM_THRESHOLD = 64 * 1024 * 1024
MMAP_THRESHOLD = 32 * 1024 * 1024


def keep_freed_heap():
    """
    Let this process keep the heap memory its plans free, for the next plan; return whether set.

    Call it once at start-up in a process that plans repeatedly (a planner node, the
    in-process engine, a benchmark). Where the C library has no `mallopt` (musl, macOS)
    nothing changes and this returns False.
    """
    mallopt = getattr(ctypes.CDLL(None), 'mallopt', None)
    if mallopt is None:
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    # Both, since setting either one turns glibc's own adjustment of the other off.
    return bool(mallopt(M_TRIM_THRESHOLD, TRIM_THRESHOLD)
                and mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD))
