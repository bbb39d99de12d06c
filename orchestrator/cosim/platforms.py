"""The platforms a native FMU carries a binary for, and their compilers.

An FMI 2.0 FMU keeps one shared library per platform in ``binaries/<platform>/``. FMI 2.0
names only x86 platforms (``win32``, ``win64``, ``linux32``, ``linux64``, ``darwin32``,
``darwin64``: "64" means 64-bit x86); since 2.0.4 (section 2.3) it says that any other
platform uses the FMI 3.0 platform tuple. So the native FMUs use

- ``linux64``: x86-64 Linux, ``<model>.so`` (the system compiler, ``$CC`` or ``cc``);
- ``win64``: x86-64 Windows, ``<model>.dll`` (MinGW-w64: ``x86_64-w64-mingw32-gcc``,
  Debian ``gcc-mingw-w64-x86-64``; the fmi2 functions exported by ``FMI2_Export``, which
  the FMI headers define as ``__declspec(dllexport)`` under ``_WIN32``, and nothing else;
  libgcc linked in, so the DLL needs only KERNEL32 and msvcrt; symbols stripped);
- ``aarch64-linux``: 64-bit ARM Linux, ``<model>.so`` (``aarch64-linux-gnu-gcc``, Debian
  ``gcc-aarch64-linux-gnu``), the FMI 3.0 tuple, as FMI 2.0.4 asks. Not ``linux64``: that
  is x86-64 and holds the x86-64 library already (fmpy 0.3 on aarch64 looks in
  ``linux64`` for FMI 2.0 binaries; pass it ``libraryPath``, docs/native.md).

The compiler of the host's own platform is ``$CC`` or ``cc``; a cross compiler's name can
be overridden by ``$CC_WIN64``, ``$CC_AARCH64_LINUX``, ``$CC_LINUX64`` (on a host that
is not x86-64 Linux). Every platform is compiled with IEEE arithmetic (no -ffast-math)
and without contracting ``a*b + c`` into a fused multiply-add (``-std=c99`` already means
``-ffp-contract=off`` in GCC; the cross builds say so explicitly): the arithmetic is the
same on every platform, only the C library's functions may differ (docs/native.md).
"""
from __future__ import annotations

import os
import platform as _platform
import shutil
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["PLATFORMS", "Platform", "host_platform", "missing_compiler", "platform_compiler",
           "resolve_platforms"]

#: the host build's flags (orchestrator.cosim.native_build.CFLAGS is this)
HOST_CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-Wall", "-Wextra")


@dataclass(frozen=True)
class Platform:
    """One platform a native FMU can carry a binary for."""

    name: str                       #: the folder under binaries/
    cc: str                         #: its (cross) compiler's name on Debian
    package: str                    #: the Debian package of that compiler
    suffix: str                     #: the shared library's suffix
    cflags: tuple[str, ...]         #: compile flags (before -I, -o and the sources)
    libs: tuple[str, ...]           #: link flags (after the sources)
    machines: tuple[str, ...]       #: platform.machine() of a Linux host of this platform

    @property
    def env(self) -> str:
        """The variable that names another compiler for it: ``CC_WIN64``."""
        return "CC_" + self.name.upper().replace("-", "_")


PLATFORMS: dict[str, Platform] = {p.name: p for p in (
    Platform("linux64", "x86_64-linux-gnu-gcc", "gcc-x86-64-linux-gnu", ".so", HOST_CFLAGS,
             ("-lm",), ("x86_64", "amd64")),
    Platform("win64", "x86_64-w64-mingw32-gcc", "gcc-mingw-w64-x86-64", ".dll",
             ("-shared", "-O2", "-std=c99", "-ffp-contract=off", "-Wall", "-Wextra"),
             ("-static-libgcc", "-s", "-lm"), ()),
    Platform("aarch64-linux", "aarch64-linux-gnu-gcc", "gcc-aarch64-linux-gnu", ".so",
             (*HOST_CFLAGS, "-ffp-contract=off"), ("-lm",), ("aarch64", "arm64")),
)}


def host_platform() -> str:
    """The platform of this machine's own compiler: ``aarch64-linux`` on 64-bit ARM Linux,
    else ``linux64`` (the project builds and runs on Linux)."""
    machine = _platform.machine().lower()
    if _platform.system() == "Linux" and machine in PLATFORMS["aarch64-linux"].machines:
        return "aarch64-linux"
    return "linux64"


def platform_compiler(name: str) -> str | None:
    """The full path of the compiler for platform ``name``, or None if it is not installed.

    The host platform's is ``$CC`` or ``cc``; another's is ``$CC_<NAME>`` or its Debian
    cross compiler (:attr:`Platform.cc`).
    """
    p = PLATFORMS[name]
    if name == host_platform():
        return shutil.which(os.environ.get("CC", "cc"))
    return shutil.which(os.environ.get(p.env, p.cc))


def missing_compiler(name: str) -> str:
    """One line: platform ``name`` has no compiler, and what to install."""
    p = PLATFORMS[name]
    if name == host_platform():
        return (f"{name}: no C compiler: {os.environ.get('CC', 'cc')!r} is not on PATH "
                "(install gcc, or set CC)")
    return (f"{name}: no cross compiler: {os.environ.get(p.env, p.cc)!r} is not on PATH "
            f"(install Debian's {p.package}, or set {p.env})")


def resolve_platforms(requested: Sequence[str] | None) -> tuple[tuple[str, ...], list[str]]:
    """The platforms to build, and a line per platform left out.

    Parameters
    ----------
    requested : Sequence[str] or None
        The platforms asked for (``--platforms``), or None: every platform whose compiler
        is installed.

    Returns
    -------
    tuple[tuple[str, ...], list[str]]
        The platforms in :data:`PLATFORMS` order, and (with ``requested`` None) one line
        per platform without a compiler, saying its binary is absent and what to install.

    Raises
    ------
    ValueError
        In one line: an unknown platform, none asked for, an explicitly requested platform
        without its compiler, or (with ``requested`` None) no compiler at all.
    """
    if requested is not None:
        unknown = [r for r in requested if r not in PLATFORMS]
        if unknown:
            raise ValueError(f"unknown platform(s) {', '.join(map(repr, unknown))} (known: "
                             f"{', '.join(PLATFORMS)})")
        if not requested:
            raise ValueError(f"no platform given (known: {', '.join(PLATFORMS)})")
        missing = [missing_compiler(r) for r in PLATFORMS if r in requested
                   and platform_compiler(r) is None]
        if missing:
            raise ValueError("; ".join(missing))
        return tuple(p for p in PLATFORMS if p in requested), []
    found = tuple(p for p in PLATFORMS if platform_compiler(p) is not None)
    notes = [missing_compiler(p) + ": its binary is not in the FMUs" for p in PLATFORMS
             if p not in found]
    if not found:
        raise ValueError("; ".join(missing_compiler(p) for p in PLATFORMS))
    return found, notes
