"""The C toolchain of the native FMUs: the compiler, its flags, the FMI headers, and
:func:`compile_fmu`, which compiles a model's C sources with its generated header into a
zipped FMU. Shared by the linear FMUs (:mod:`orchestrator.cosim.native`) and the guidance
FMUs (:mod:`orchestrator.cosim.native_guidance`).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path

from ..atomic import copy_atomically, temporary_sibling
from .build import FMU_KINDS, ROOT, fmu_cache_dir

__all__ = ["CFLAGS", "FMI_HEADERS", "NATIVE_DIR", "NativeBuildError", "compile_fmu", "compiler",
           "native_model"]

NATIVE_DIR = ROOT / "fmu_common" / "native"
#: how the shared library is built (IEEE arithmetic kept: no -ffast-math)
CFLAGS = ("-shared", "-fPIC", "-O2", "-std=c99", "-Wall", "-Wextra")
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h")


class NativeBuildError(RuntimeError):
    """A native FMU cannot be built (no compiler, the compiler failed)."""


def native_model(kind: str) -> str:
    """The model identifier of a kind's native FMU: ``AuvController`` -> ``AuvControllerNative``."""
    return f"{FMU_KINDS[kind].model}Native"


def compiler() -> str:
    """The C compiler: ``$CC`` or ``cc``.

    Raises
    ------
    NativeBuildError
        If there is none on PATH (one line saying what to install).
    """
    cc = os.environ.get("CC", "cc")
    path = shutil.which(cc)
    if path is None:
        raise NativeBuildError(f"no C compiler: {cc!r} is not on PATH (install gcc, or set CC)")
    return path


def _fmi_include() -> Path:
    import fmpy
    return Path(fmpy.__file__).parent / "c-code"


def _cached_library(model: str, guid: str, cc: str) -> Path:
    """Where the compiled library of ``model`` with this GUID (a digest of its sources and
    its generated header, start values included) and this compiler is kept: the FMU
    cache's ``native/`` folder (:func:`orchestrator.cosim.build.fmu_cache_dir`), so a
    second run of the same design links nothing."""
    key = hashlib.sha256("\n".join((guid, cc, *CFLAGS)).encode()).hexdigest()[:24]
    return fmu_cache_dir() / "native" / f"{model}-{key}.so"


def compile_fmu(model: str, sources: tuple[Path, ...], headers: tuple[Path, ...],
                header: Callable[[str], str], description: Callable[[str], bytes],
                out_dir: Path | str) -> Path:
    """Compile ``sources`` with the generated ``native_model.h`` and zip ``<model>.fmu``
    (the library taken from the FMU cache when this design was compiled before).

    Parameters
    ----------
    model : str
        Model identifier (the library's name).
    sources, headers : tuple[Path, ...]
        The C files compiled and shipped in sources/ (beside the FMI headers).
    header, description : Callable[[str], ...]
        native_model.h and modelDescription.xml for a GUID (the GUID is a digest of the
        sources and of the header without it).
    out_dir : Path or str
        Destination folder (created if missing); the .fmu is written atomically.

    Returns
    -------
    Path
        The .fmu.

    Raises
    ------
    NativeBuildError
        No compiler, or the compiler failed (its first error line).
    """
    cc = compiler()
    digest = hashlib.sha256()
    for f in (*sources, *headers):
        digest.update(f.read_bytes())
    digest.update(header("").encode())
    guid = "{" + digest.hexdigest()[:32] + "}"
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="auv_native_") as tmp:
        src = Path(tmp) / "sources"
        src.mkdir()
        for f in (*sources, *headers):
            shutil.copy2(f, src / f.name)
        (src / "native_model.h").write_text(header(guid))
        for name in FMI_HEADERS:
            shutil.copy2(_fmi_include() / name, src / name)
        lib = Path(tmp) / f"{model}.so"
        cached = _cached_library(model, guid, cc)
        if cached.is_file():
            shutil.copyfile(cached, lib)
        else:
            cmd = [cc, *CFLAGS, f"-I{src}", "-o", str(lib),
                   *(str(src / f.name) for f in sources), "-lm"]
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                first = next((ln for ln in r.stderr.splitlines() if "error" in ln),
                             r.stderr.strip())
                raise NativeBuildError(f"building {model}: {first}")
            try:
                cached.parent.mkdir(parents=True, exist_ok=True)
                copy_atomically(lib, cached)
            except OSError:                 # a read-only cache: compile every time
                pass
        fmu = out / f"{model}.fmu"
        with temporary_sibling(fmu) as part, zipfile.ZipFile(part, "w",
                                                              zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", description(guid))
            for f in sorted(src.iterdir()):
                z.write(f, f"sources/{f.name}")
            z.write(lib, f"binaries/linux64/{model}.so")
    return fmu
