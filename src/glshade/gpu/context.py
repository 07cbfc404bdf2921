"""The OpenGL context: headless EGL through moderngl/glcontext.

On a machine without a GPU, EGL runs on Mesa's llvmpipe (a real GL 4.5 core context with
fp64). ``GLSHADE_EGL_DEVICE`` (or ``device_index``) picks the EGL device on a multi-GPU
machine; ``GLSHADE_LIBEGL`` overrides the EGL library that glcontext loads.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import moderngl

from glshade.errors import ContextError

#: GL version the shaders are written for (``#version 450``; fp64 is core since 4.0).
REQUIRED_GL = 450

INSTALL_HINT = (
    "install the Debian packages libegl1 and libgl1-mesa-dri "
    "(apt-get install libegl1 libgl1-mesa-dri), or a GPU driver with EGL"
)


@contextlib.contextmanager
def interrupts_deferred() -> Iterator[None]:
    """SIGINT held back in this thread for the ``with`` block, then delivered (a Ctrl-C
    meanwhile raises ``KeyboardInterrupt`` as the block ends).

    For a driver's shader compile: Mesa's llvmpipe compiles with LLVM, which does not
    survive a signal handler interrupting its system calls (measured: every process that
    took a stream of SIGINTs while compiling ended in a segmentation fault; with the signal
    held back, none did). Python handles signals on the main thread, which this blocks them
    on (the kernel hands a Ctrl-C to another thread meanwhile, whose waits restart); in
    any other thread it does nothing."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread() or not hasattr(
        signal, "pthread_sigmask"
    ):
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


@dataclass(frozen=True)
class ContextInfo:
    """What ``glshade info`` prints."""

    renderer: str
    vendor: str
    version: str
    version_code: int
    fp64: bool
    max_texture_size: int
    device_index: int

    def lines(self) -> list[str]:
        return [
            f"renderer:         {self.renderer}",
            f"vendor:           {self.vendor}",
            f"GL version:       {self.version} (code {self.version_code})",
            f"fp64 shaders:     {'yes' if self.fp64 else 'no'}",
            f"max texture size: {self.max_texture_size}",
            f"EGL device index: {self.device_index}",
        ]


def _device_index_from_env() -> int:
    raw = os.environ.get("GLSHADE_EGL_DEVICE", "0")
    try:
        index = int(raw)
    except ValueError:
        index = -1
    if index < 0:
        raise ContextError(f"GLSHADE_EGL_DEVICE: must be an integer >= 0, got {raw!r}")
    return index


def _loadable(soname: str) -> str | None:
    """``soname`` when the dynamic loader finds it (what glcontext would pick: it asks
    ``ctypes.util.find_library``, which runs ``ldconfig`` in a subprocess, a few ms per
    library); None leaves the search to glcontext."""
    try:
        ctypes.CDLL(soname)
    except OSError:
        return None
    return soname


def egl_devices(count: int, libegl: str | None = None) -> list[str]:
    """``"index: GL renderer"`` for EGL devices ``0 … count-1`` (a device that gives no
    context says why)."""
    names = []
    for index in range(count):
        kwargs: dict[str, Any] = {"backend": "egl", "device_index": index, "require": REQUIRED_GL}
        if libegl:
            kwargs["libegl"] = libegl
        try:
            ctx = moderngl.create_standalone_context(**kwargs)
        except Exception as exc:  # glcontext raises bare Exception
            names.append(f"{index}: no context ({' '.join(str(exc).split())})")
            continue
        names.append(f"{index}: {ctx.info.get('GL_RENDERER', '?')}")
        ctx.release()
    return names


def _missing_device(index: int, count: int, libegl: str | None) -> str:
    devices = "; ".join(egl_devices(count, libegl))
    return (
        f"--device {index}: must be an EGL device index in [0, {count - 1}]; found {count} device"
        f"{'s' if count > 1 else ''}: {devices}"
    )


def released_finish(ctx: moderngl.Context) -> Any:
    """``glFinish`` as a ctypes function (ctypes releases the interpreter lock for the
    call), from the loader moderngl took its functions from; None where there is none."""
    load = getattr(getattr(ctx.mglo, "_context", None), "load", None)
    try:
        address = load("glFinish") if load is not None else 0
    except Exception:  # a loader of another kind: moderngl's own finish instead
        return None
    return ctypes.CFUNCTYPE(None)(address) if address else None


class GLContext:
    """Owns one standalone EGL context; a context manager. ``release()`` twice is harmless."""

    _known: ContextInfo | None  # info(), once asked

    @classmethod
    def wrap(cls, ctx: moderngl.Context) -> GLContext:
        """Adopt a context someone else owns and keeps current (a viewer window's): glshade
        renders into it without switching contexts, and ``release`` leaves it alone."""
        if ctx.version_code < REQUIRED_GL:
            raise ContextError(
                f"OpenGL {ctx.info.get('GL_VERSION', '?')} is too old: glshade needs 4.5 core"
            )
        self = cls.__new__(cls)
        self._known = None
        self.device_index = -1
        self.ctx = ctx
        self._external = True
        self._depth = 0
        self._finish = None
        self._parking_texture = ctx.renderbuffer((1, 1), 1, dtype="f1")
        self._parking = ctx.framebuffer(color_attachments=[self._parking_texture])
        return self

    def __init__(self, device_index: int | None = None, libegl: str | None = None) -> None:
        self._external = False
        self._finish: Any = None
        self._known = None
        self.device_index = _device_index_from_env() if device_index is None else int(device_index)
        if self.device_index < 0:
            raise ContextError(f"device_index: must be an integer >= 0, got {self.device_index}")
        # ask for 4.5 by name: moderngl asks for 3.3 by default, which Mesa answers with its
        # highest core profile but NVIDIA's driver with exactly 3.3
        kwargs: dict[str, Any] = {
            "backend": "egl",
            "device_index": self.device_index,
            "require": REQUIRED_GL,
        }
        libegl = libegl or os.environ.get("GLSHADE_LIBEGL") or _loadable("libEGL.so.1")
        if libegl:
            kwargs["libegl"] = libegl
        libgl = _loadable("libGL.so.1")
        if libgl:
            kwargs["libgl"] = libgl
        try:
            self.ctx: moderngl.Context | None = moderngl.create_standalone_context(**kwargs)
        except Exception as exc:  # glcontext raises bare Exception for every failure
            reason = " ".join(str(exc).split()) or type(exc).__name__
            found = re.search(r"found (\d+) devices?", reason)
            if found is not None and self.device_index >= int(found.group(1)) > 0:
                raise ContextError(
                    _missing_device(self.device_index, int(found.group(1)), libegl)
                ) from None
            raise ContextError(
                f"no OpenGL context through EGL (device {self.device_index}): {reason}; "
                f"{INSTALL_HINT}"
            ) from None
        if self.ctx.version_code < REQUIRED_GL:
            version = self.ctx.info.get("GL_VERSION", "?")
            self.release()
            raise ContextError(
                f"OpenGL {version} is too old: glshade needs 4.5 core; {INSTALL_HINT}"
            )
        self._depth = 0
        # A 1x1 framebuffer to bind while others are released: moderngl re-binds the
        # framebuffer it last bound whenever it creates another, so that one must never
        # be deleted while bound (a standalone context has no default framebuffer).
        with self.current():
            self._parking_texture = self.ctx.renderbuffer((1, 1), 1, dtype="f1")
            self._parking = self.ctx.framebuffer(color_attachments=[self._parking_texture])
        info = self.info()
        # Logged where the process uses logging: a process that never imported it has no
        # handler that would show an info line, and importing it costs ~3 ms of start-up.
        logging = sys.modules.get("logging")
        if logging is not None:
            logging.getLogger("glshade").info(
                "GL context: %s, GL %s, fp64 %s", info.renderer, info.version, info.fp64
            )

    def info(self) -> ContextInfo:
        """What the context is (queried once, it never changes; an error once released)."""
        self._live()
        if self._known is None:
            with self.current() as ctx:
                self._known = self._info(ctx)
        return self._known

    def _info(self, ctx: moderngl.Context) -> ContextInfo:
        return ContextInfo(
            renderer=ctx.info["GL_RENDERER"],
            vendor=ctx.info["GL_VENDOR"],
            version=ctx.info["GL_VERSION"],
            version_code=ctx.version_code,
            fp64=ctx.version_code >= 400 or "GL_ARB_gpu_shader_fp64" in ctx.extensions,
            max_texture_size=int(ctx.info["GL_MAX_TEXTURE_SIZE"]),
            device_index=self.device_index,
        )

    @property
    def gl(self) -> moderngl.Context:
        """The live moderngl context (an error once released)."""
        return self._live()

    def _live(self) -> moderngl.Context:
        if self.ctx is None:
            raise ContextError("the GL context has been released")
        return self.ctx

    @contextlib.contextmanager
    def current(self) -> Iterator[moderngl.Context]:
        """``with context.current() as ctx:`` makes this context current for the block.

        Re-entrant: only the outermost block switches contexts, because glcontext's EGL
        exit makes *no* context current (it does not restore the previous one). Every GL
        call of glshade runs inside such a block, so several contexts can share a thread.
        """
        ctx = self._live()
        if self._external:  # its owner keeps it current
            yield ctx
            return
        if self._depth == 0:
            ctx.__enter__()
        self._depth += 1
        try:
            yield ctx
        finally:
            self._depth -= 1
            if self._depth == 0:
                ctx.__exit__(None, None, None)

    def wait(self) -> None:
        """Block until the GL has done every command issued so far (a draw's trace), with
        Python's interpreter lock released: moderngl's calls keep it, so its ``finish``
        would stop every other Python thread (the engine's analysis) for a whole llvmpipe
        trace. glFinish is called through the function the context's own loader gives
        moderngl; a context whose loader cannot be asked finishes through moderngl."""
        with self.current() as ctx:
            if self._finish is None:
                self._finish = released_finish(ctx) or ctx.finish
            self._finish()

    def park(self) -> None:
        """Bind the context's own 1x1 framebuffer (call before releasing a bound one)."""
        with self.current():
            self._parking.use()

    def check_error(self, where: str = "") -> None:
        """Raise if GL has recorded an error (tests call this around each render)."""
        with self.current() as ctx:
            error = ctx.error
        if error != "GL_NO_ERROR":
            raise RuntimeError(f"OpenGL error {error}" + (f" after {where}" if where else ""))

    def release(self) -> None:
        if self.ctx is not None:
            if self._external:
                self._parking.release()
                self._parking_texture.release()
            else:
                self.ctx.release()  # destroys the EGL context and every object in it
            self.ctx = None

    def __enter__(self) -> GLContext:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def set_uniform(program: moderngl.Program | moderngl.ComputeShader, name: str, value: Any) -> None:
    """Write a uniform's value: a list of values for an array, also for an array of one
    element (which moderngl writes as a single value)."""
    uniform = program[name]
    if isinstance(value, list) and getattr(uniform, "array_length", 1) == 1 and len(value) == 1:
        value = value[0]
    uniform.value = value  # type: ignore[union-attr]
