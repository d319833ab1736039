"""One code path for the numerical kernels, so that every x86-64 machine prints the same bytes.

OpenBLAS (under NumPy and SciPy, and under the SDP solver through SciPy's LAPACK) picks
its kernels for the CPU it finds at load time, and NumPy dispatches its loops to the
widest vector unit the CPU has. Each choice computes the same results to within
rounding, but not the same bits: a fused multiply-add, another blocking or another
polynomial moves the last digit. The robust LMI designs amplify such differences (their
starting SDP solution is not unique, their sequential linear programs land on other
vertices), so before this module they reached other designs on other CPUs.

:func:`pin_numeric_kernels` fixes both choices before NumPy is first imported, the way
Intel's MKL fixes its code path for conditional numerical reproducibility
(``MKL_CBWR``): OpenBLAS's Haswell kernels (``OPENBLAS_CORETYPE=Haswell``; AVX2 and
FMA) and NumPy's x86-64-v3 loops (its wider targets disabled through
``NPY_DISABLE_CPU_FEATURES``). Every Intel CPU since Haswell (2013) and every AMD CPU
since Excavator (2015) has both, so they all run the same instructions. A CPU without
AVX2 and FMA keeps its own kernels (its results may differ in the last digits); so does
a process that imported NumPy before ``bdft`` (the library used from another program),
and ``BDFT_NATIVE_KERNELS=1`` asks for the CPU's own kernels on purpose. The cost,
measured on the machine of the README's figures, is in the README.

This module imports nothing numerical: it must run first.
"""

from __future__ import annotations

import os
import platform
import sys

__all__ = [
    "NATIVE_ENV",
    "OPENBLAS_KERNEL",
    "NUMPY_DISABLED",
    "pin_numeric_kernels",
    "pinned",
]

#: Environment variable that, set to 1, leaves OpenBLAS and NumPy their own choice.
NATIVE_ENV = "BDFT_NATIVE_KERNELS"
#: The OpenBLAS kernel family every x86-64 CPU with AVX2 and FMA runs.
OPENBLAS_KERNEL = "Haswell"
#: NumPy's dispatch targets wider than x86-64-v3 (NumPy 2's names), disabled.
NUMPY_DISABLED = ("X86_V4", "AVX512_ICL", "AVX512_SPR")

_state = {"pinned": False, "reason": "not attempted"}


def _cpu_flags() -> set[str]:
    """The CPU's feature flags (Linux ``/proc/cpuinfo``; empty where it cannot be read)."""
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("flags"):
                    return set(line.split(":", 1)[1].split())
    except OSError:
        pass
    return set()


def pin_numeric_kernels(environ=None, modules=None) -> bool:
    """Fix OpenBLAS's and NumPy's kernels for this process and the processes it starts.

    Sets ``OPENBLAS_CORETYPE`` to :data:`OPENBLAS_KERNEL` and adds :data:`NUMPY_DISABLED`
    to ``NPY_DISABLE_CPU_FEATURES`` (the worker processes of joblib and of a local Dask
    cluster inherit them), unless ``BDFT_NATIVE_KERNELS=1``, NumPy is already imported
    (too late: the kernels are chosen at load time), the machine is not x86-64 or its CPU
    lacks AVX2 or FMA (it could not run those kernels).

    Parameters
    ----------
    environ : mapping, optional
        The environment to change (default: ``os.environ``).
    modules : mapping, optional
        The loaded modules (default: ``sys.modules``).

    Returns
    -------
    bool
        Whether the kernels were pinned; :func:`pinned` tells why not.
    """
    env = os.environ if environ is None else environ
    mods = sys.modules if modules is None else modules
    if env.get(NATIVE_ENV, "").strip() == "1":
        reason = f"{NATIVE_ENV}=1: the CPU's own kernels"
    elif "numpy" in mods:
        reason = "NumPy was imported before bdft: its kernels were already chosen"
    elif platform.machine().lower() not in ("x86_64", "amd64"):
        reason = f"not an x86-64 machine ({platform.machine()})"
    elif not {"avx2", "fma"} <= _cpu_flags():
        reason = "the CPU lacks AVX2 or FMA (or its flags cannot be read)"
    else:
        env["OPENBLAS_CORETYPE"] = OPENBLAS_KERNEL
        have = env.get("NPY_DISABLE_CPU_FEATURES", "").replace(",", " ").split()
        env["NPY_DISABLE_CPU_FEATURES"] = " ".join(
            [*have, *(f for f in NUMPY_DISABLED if f not in have)]
        )
        reason = f"OpenBLAS {OPENBLAS_KERNEL}, NumPy x86-64-v3"
        _state.update(pinned=True, reason=reason)
        return True
    _state.update(pinned=False, reason=reason)
    return False


def pinned() -> tuple[bool, str]:
    """Whether this process pinned its kernels, and which (or why not).

    Returns
    -------
    (bool, str)
    """
    return bool(_state["pinned"]), str(_state["reason"])
