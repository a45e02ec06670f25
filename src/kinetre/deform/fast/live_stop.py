"""A live solve's stop: a frame ends after a step once a newer frame waits and it has had its share of CPU.

The flag is one byte that whoever receives frames sets, possibly in another process (the studio's solve
worker shares it through `multiprocessing.RawValue`), read as a numpy uint8 view so that the numba Gauss-
Newton loop (`gauss_newton.py`) reads it between its steps as well as the Python loops. The share is
counted on the solving thread's CPU clock (CLOCK_THREAD_CPUTIME_ID, `time.thread_time`'s clock): wall time
would count the waits for a core on a busy machine. numba has no such clock, so `thread_cpu_time` calls
libc's clock_gettime by name (an external symbol, not a ctypes pointer: the kernels stay cacheable),
once per accepted step and only with a flag given.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from ...jit import intrinsic, njit

CLOCK = getattr(time, "CLOCK_THREAD_CPUTIME_ID", 3)  # Linux's value when the platform does not say
NO_FLAG = np.zeros(0, np.uint8)  # no stop: the offline solve


@intrinsic
def _thread_cpu_ns(typingctx):
    from llvmlite import ir  # numba is loaded when this runs (the intrinsic is typed inside a compilation)
    from numba import types
    from numba.core import cgutils

    def codegen(context, builder, signature, args):
        i32, i64 = ir.IntType(32), ir.IntType(64)
        timespec = ir.LiteralStructType([i64, i64])  # tv_sec, tv_nsec (LP64)
        clock_gettime = cgutils.get_or_insert_function(builder.module, ir.FunctionType(
            i32, [i32, timespec.as_pointer()]), "clock_gettime")
        ts = cgutils.alloca_once(builder, timespec)
        builder.call(clock_gettime, [ir.Constant(i32, CLOCK), ts])
        seconds = builder.load(cgutils.gep_inbounds(builder, ts, 0, 0))
        nanoseconds = builder.load(cgutils.gep_inbounds(builder, ts, 0, 1))
        return builder.add(builder.mul(seconds, ir.Constant(i64, 1_000_000_000)), nanoseconds)
    return types.int64(), codegen


@njit(cache=True)
def thread_cpu_time() -> float:
    """The calling thread's CPU time in seconds, on `time.thread_time`'s clock."""
    return _thread_cpu_ns() * 1e-9


@njit(cache=True)
def should_stop(flag, after) -> bool:
    """In a kernel, after an accepted step: a newer frame waits (flag[0] set) and the thread's CPU clock is
    past `after`. The clock is read first: an opaque call, so the flag (another process's write) is loaded
    afresh after it rather than once before the loop."""
    return flag.shape[0] > 0 and thread_cpu_time() > after and flag[0] != 0


@dataclass(frozen=True)
class Yield:
    """`Rig.solve`'s `stop` for a live solve: a newer frame waits (`flag[0]` nonzero) and this frame's solve
    is past `after` (seconds on the thread's CPU clock, `time.thread_time`). The PCG loop reads both
    between its steps inside numba; as a callable it serves the exact loop."""

    flag: np.ndarray  # uint8 (1,), shared with whoever receives the frames
    after: float

    def __post_init__(self):
        if self.flag.dtype != np.uint8 or self.flag.shape != (1,):
            raise ValueError(f"Yield.flag must be a uint8 array of shape (1,), got {self.flag.dtype} "
                             f"{self.flag.shape}")

    @classmethod
    def after_share(cls, flag: np.ndarray, share: float) -> "Yield":
        """Yield once this thread has spent `share` more CPU seconds from now."""
        return cls(flag, time.thread_time() + share)

    def __call__(self) -> bool:
        return bool(self.flag[0]) and time.thread_time() > self.after
