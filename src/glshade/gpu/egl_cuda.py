"""Which EGL device is this process's CUDA GPU? (for one Dask worker per GPU)

EGL enumerates every GPU whatever ``CUDA_VISIBLE_DEVICES`` says, so a worker that
dask-cuda's ``LocalCUDACluster`` (or SLURM) pinned to one GPU would still open EGL device
0 and all workers would share the first GPU. NVIDIA's ``EGL_NV_device_cuda`` extension
tells, per EGL device, its CUDA device number (``EGL_CUDA_DEVICE_NV``) in this process's
enumeration, which ``CUDA_VISIBLE_DEVICES`` restricts and reorders: the worker's GPU is
the visible device 0 (the practice of cuda-python's test helpers, NVIDIA/cuda-python#2865).

Order of precedence: ``GLSHADE_EGL_DEVICE`` (an explicit choice); the EGL device whose
CUDA number is 0 when ``CUDA_VISIBLE_DEVICES`` is set and the driver offers the extension;
else EGL device 0. Mesa (llvmpipe) offers no such extension: device 0.
"""

from __future__ import annotations

import ctypes
import os
from collections.abc import Sequence

EGL_EXTENSIONS = 0x3055
EGL_CUDA_DEVICE_NV = 0x323A
MAX_DEVICES = 32


def egl_index_for_cuda(cuda_numbers: Sequence[int | None], cuda_device: int = 0) -> int | None:
    """The EGL index whose CUDA number is ``cuda_device`` (None: no such device, or the
    numbers are not a consistent map: two EGL devices claiming one CUDA device)."""
    known = [n for n in cuda_numbers if n is not None]
    if len(set(known)) != len(known):
        return None
    for index, number in enumerate(cuda_numbers):
        if number == cuda_device:
            return index
    return None


def egl_cuda_numbers(libegl: str | None = None) -> list[int | None]:
    """Each EGL device's CUDA device number (None for a device without one), in the order
    of ``eglQueryDevicesEXT`` (glcontext's ``device_index``); [] when EGL cannot say."""
    try:
        lib = ctypes.CDLL(libegl or "libEGL.so.1")
    except OSError:
        return []
    get_proc = lib.eglGetProcAddress
    get_proc.restype, get_proc.argtypes = ctypes.c_void_p, [ctypes.c_char_p]
    addresses = [
        get_proc(name)
        for name in (b"eglQueryDevicesEXT", b"eglQueryDeviceStringEXT", b"eglQueryDeviceAttribEXT")
    ]
    if not all(addresses):
        return []
    query_devices = ctypes.CFUNCTYPE(
        ctypes.c_uint, ctypes.c_int, ctypes.POINTER(ctypes.c_void_p), ctypes.POINTER(ctypes.c_int)
    )(addresses[0])
    query_string = ctypes.CFUNCTYPE(ctypes.c_char_p, ctypes.c_void_p, ctypes.c_int)(addresses[1])
    query_attrib = ctypes.CFUNCTYPE(
        ctypes.c_uint, ctypes.c_void_p, ctypes.c_int, ctypes.POINTER(ctypes.c_ssize_t)
    )(addresses[2])
    devices = (ctypes.c_void_p * MAX_DEVICES)()
    count = ctypes.c_int(0)
    if not query_devices(MAX_DEVICES, devices, ctypes.byref(count)):
        return []
    numbers: list[int | None] = []
    for device in devices[: count.value]:
        extensions = (query_string(device, EGL_EXTENSIONS) or b"").split()
        value = ctypes.c_ssize_t(-1)
        has = b"EGL_NV_device_cuda" in extensions and query_attrib(
            device, EGL_CUDA_DEVICE_NV, ctypes.byref(value)
        )
        numbers.append(int(value.value) if has else None)
    return numbers


def worker_egl_device(
    environ: os._Environ | dict = os.environ, libegl: str | None = None
) -> int | None:
    """The EGL device index a worker should open (None: leave it to ``GLSHADE_EGL_DEVICE``
    or device 0, :class:`glshade.gpu.context.GLContext`'s own rule)."""
    if environ.get("GLSHADE_EGL_DEVICE") or not environ.get("CUDA_VISIBLE_DEVICES", "").strip():
        return None
    return egl_index_for_cuda(egl_cuda_numbers(libegl), 0)
