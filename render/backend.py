"""Mitsuba 3 variant choice: CUDA, then LLVM, then scalar; never a crash for a missing backend.

Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` once, when it is first imported, so
``import_mitsuba`` points it at a standard system ``libLLVM`` (if unset) *before*
importing. Mitsuba's variant is process-global (``mi.set_variant``); everything in
``render`` that builds or renders a scene calls ``use_variant`` first, so tests and
benchmarks can switch variants freely inside one process.
"""
from __future__ import annotations

import glob
import logging
import os
from typing import NamedTuple

from mnacore.errors import MnaError

log = logging.getLogger("mna.render")

#: preference order of the RGB variants we render with
VARIANT_ORDER = ("cuda_ad_rgb", "llvm_ad_rgb", "scalar_rgb")

#: standard locations of the LLVM shared library (newest first within each pattern)
LLVM_SEARCH = (
    "/usr/lib/x86_64-linux-gnu/libLLVM-*.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.*",
    "/usr/lib/aarch64-linux-gnu/libLLVM-*.so",
    "/usr/lib/aarch64-linux-gnu/libLLVM.so.*",
    "/usr/lib/llvm-*/lib/libLLVM.so",
    "/usr/lib64/libLLVM*.so*",
    "/usr/local/lib/libLLVM*.so*",
    "/opt/homebrew/opt/llvm/lib/libLLVM.dylib",
    "/usr/local/opt/llvm/lib/libLLVM.dylib",
)

_mi = None


def find_libllvm() -> str | None:
    """First existing libLLVM in ``LLVM_SEARCH`` (highest version first), or None."""
    def version(path: str) -> tuple:
        digits = "".join(c if c.isdigit() else " " for c in os.path.basename(path)).split()
        return tuple(int(d) for d in digits)

    for pattern in LLVM_SEARCH:
        hits = sorted(glob.glob(pattern), key=version, reverse=True)
        if hits:
            return hits[0]
    return None


def import_mitsuba():
    """Import and return ``mitsuba``, pointing Dr.Jit at a system libLLVM first if none is set."""
    global _mi
    if _mi is None:
        if not os.environ.get("DRJIT_LIBLLVM_PATH"):
            lib = find_libllvm()
            if lib:
                os.environ["DRJIT_LIBLLVM_PATH"] = lib
        try:
            import mitsuba
        except ImportError as exc:  # pragma: no cover - mitsuba is a dependency
            # a missing backend is the user's environment, not a bug: one line, exit 2
            raise MnaError(f"Mitsuba 3 is not installed ({exc}); pip install mitsuba") from None
        _mi = mitsuba
    return _mi


def _backend_ok(variant: str) -> bool:
    import drjit as dr

    if variant.startswith("cuda_"):
        return bool(dr.has_backend(dr.JitBackend.CUDA))
    if variant.startswith("llvm_"):
        return bool(dr.has_backend(dr.JitBackend.LLVM))
    return True


def available_variants() -> list[str]:
    """RGB variants that are compiled in *and* whose backend initialised, in preference order."""
    mi = import_mitsuba()
    compiled = set(mi.variants())
    return [v for v in VARIANT_ORDER if v in compiled and _backend_ok(v)]


class VariantChoice(NamedTuple):
    variant: str
    warning: str | None
    """set when the requested or preferred variant was not usable and we fell back."""


def choose_variant(requested: str | None = None) -> VariantChoice:
    """The variant to render with: ``requested`` if usable, else the best available.

    An unknown variant name is a ``ValueError``; a known one whose backend is missing
    (no GPU, no libLLVM) falls back with a warning, never an error.
    """
    mi = import_mitsuba()
    avail = available_variants()
    if requested:
        if requested not in mi.variants():
            raise ValueError(f"--variant: unknown Mitsuba variant {requested!r}; compiled variants: "
                             f"{', '.join(v for v in mi.variants() if v.endswith('_rgb'))}")
        if not requested.endswith("_rgb"):
            raise ValueError(f"--variant: {requested!r} is not an RGB variant; use one of "
                             f"{', '.join(VARIANT_ORDER)}")
        if requested in avail:
            return VariantChoice(requested, None)
        msg = (f"Mitsuba variant {requested} is not usable here ({_missing_reason(requested)}); "
               f"falling back to {avail[0]}")
        log.warning(msg)
        return VariantChoice(avail[0], msg)
    warning = None
    # only the slow fallback is worth a warning: CUDA, when it works, is preferred anyway
    if avail[0] == "scalar_rgb" and "llvm_ad_rgb" in mi.variants():
        warning = (f"Mitsuba LLVM backend unavailable ({_missing_reason('llvm_ad_rgb')}); "
                   f"rendering with {avail[0]} (about 10x slower)")
        log.warning(warning)
    return VariantChoice(avail[0], warning)


def _missing_reason(variant: str) -> str:
    if variant.startswith("cuda_"):
        return "no CUDA GPU"
    path = os.environ.get("DRJIT_LIBLLVM_PATH")
    return (f"libLLVM could not be loaded from DRJIT_LIBLLVM_PATH={path}" if path
            else "no libLLVM found; install libllvm or set DRJIT_LIBLLVM_PATH")


def use_variant(variant: str):
    """``mi.set_variant(variant)`` and return the ``mitsuba`` module."""
    mi = import_mitsuba()
    if mi.variant() != variant:
        mi.set_variant(variant)
    return mi
