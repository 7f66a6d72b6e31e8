"""Stage ``masks``, scratch arrays: the large per-frame arrays (the planes' signed distances
and label images, a few MB per frame) kept from one frame to the next in each thread.

A fresh array of that size is new memory each frame, and the kernel's zeroing of its pages
on first touch cost more than the work written into them (measured: the label images and
distances of six planes, 0.8 ms into kept arrays, 2.4 ms into fresh ones). The arrays are
owned by the thread that asked for them and live until its next request of the same name:
only :func:`detect_fronts`' own stages use them, within one call."""

import threading

import numpy as np

_LOCAL = threading.local()


def scratch(name: str, shape: tuple, dtype) -> np.ndarray:
    """An uninitialised C-contiguous array of ``shape`` and ``dtype``, the memory of this
    thread's last array of that ``name`` when large enough (then its values are left over
    from that use). An earlier array of the same name and thread must no longer be in use."""
    pool = getattr(_LOCAL, "pool", None)
    if pool is None:
        pool = _LOCAL.pool = {}
    dtype = np.dtype(dtype)
    size = int(np.prod(shape, dtype=np.int64))
    buf = pool.get(name)
    if buf is None or buf.dtype != dtype or buf.size < size:
        buf = pool[name] = np.empty(size, dtype)
    return buf[:size].reshape(shape)
