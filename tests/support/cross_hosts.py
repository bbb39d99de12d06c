"""The C host of orchestrator/interop/native_host/c_host.c on other platforms: compiled with the cross compilers
of :mod:`orchestrator.cosim.platforms` and run under ``wine`` (win64) or ``qemu-aarch64 -L
/usr/aarch64-linux-gnu`` (aarch64-linux), so the exported native FMUs' other binaries are
run for real on this x86-64 Linux machine."""
from __future__ import annotations

import os
import shutil
import subprocess
from dataclasses import dataclass, field
from pathlib import Path

from orchestrator.cosim.platforms import PLATFORMS, host_platform, platform_compiler
from orchestrator.interop.c_host import C_HOST_SOURCE

__all__ = ["AARCH64_SYSROOT", "CrossHost", "build_host", "host_system", "missing_tools",
           "stop_wine"]

C_HOST = C_HOST_SOURCE
#: the aarch64 C library of Debian's libc6-arm64-cross (qemu-aarch64 -L)
AARCH64_SYSROOT = Path("/usr/aarch64-linux-gnu")


def _wine() -> str | None:
    for name in ("wine64", "wine"):
        if shutil.which(name):
            return shutil.which(name)
    return "/usr/lib/wine/wine64" if os.access("/usr/lib/wine/wine64", os.X_OK) else None


def _wineserver() -> str | None:
    for cand in (shutil.which("wineserver"), "/usr/lib/wine/wineserver"):
        if cand and os.access(cand, os.X_OK):
            return cand
    return None


def missing_tools(platform: str) -> str | None:
    """Why the C host cannot run on ``platform`` here (the programs and Debian packages
    missing), or None."""
    missing = []
    if platform_compiler(platform) is None:
        p = PLATFORMS[platform]
        missing.append(f"{os.environ.get(p.env, p.cc)} (Debian {p.package}, or set {p.env})")
    if platform == "win64" and _wine() is None:
        missing.append("wine64 (Debian wine64 and wine)")
    if platform == "aarch64-linux":
        if shutil.which("qemu-aarch64") is None:
            missing.append("qemu-aarch64 (Debian qemu-user)")
        if not (AARCH64_SYSROOT / "lib" / "ld-linux-aarch64.so.1").exists():
            missing.append(f"{AARCH64_SYSROOT}/lib/ld-linux-aarch64.so.1 (Debian "
                           "libc6-arm64-cross)")
    return f"{platform}: missing {', '.join(missing)}" if missing else None


@dataclass
class CrossHost:
    """The C host built for one platform and how to run it here."""

    platform: str
    exe: Path
    wrapper: tuple[str, ...] = ()
    env: dict[str, str] = field(default_factory=dict)

    def path(self, p: Path | str) -> str:
        """How this host names the file ``p`` of this machine (wine: drive Z: is /)."""
        if self.platform == "win64":
            return "Z:" + str(Path(p).resolve()).replace("/", "\\")
        return str(Path(p).resolve())

    def run(self, sysfile: Path, steps: int, h: float, out_csv: Path,
            timeout: float = 600) -> subprocess.CompletedProcess:
        """``c_host SYSTEM_FILE STEPS H OUT_CSV``, files named the host's way."""
        cmd = [*self.wrapper, str(self.exe), self.path(sysfile), str(steps), repr(h),
               self.path(out_csv)]
        return subprocess.run(cmd, capture_output=True, text=True, env=self.env,
                              timeout=timeout)


def build_host(platform: str, out_dir: Path, wineprefix: Path | None = None) -> CrossHost:
    """Compile the C host for ``platform`` into ``out_dir`` (-O2, C99, the FMI headers of
    fmpy; for win64 MinGW's correctly rounded stdio and libgcc linked in).

    Parameters
    ----------
    platform : str
        A name of :data:`~orchestrator.cosim.platforms.PLATFORMS`.
    out_dir : Path
        Where the executable goes.
    wineprefix : Path or None, optional
        The wine prefix for win64 (created by wine on first use), default ``out_dir/wine``.

    Returns
    -------
    CrossHost
        The executable, the emulator to run it with and its environment.
    """
    import fmpy
    inc = Path(fmpy.__file__).parent / "c-code"
    cc = platform_compiler(platform)
    if cc is None:
        raise RuntimeError(missing_tools(platform))
    out_dir.mkdir(parents=True, exist_ok=True)
    base = [cc, "-O2", "-std=c99", "-Wall", "-Wextra", f"-I{inc}"]
    if platform == "win64":
        exe = out_dir / "c_host.exe"
        cmd = [*base, "-D__USE_MINGW_ANSI_STDIO=1", "-o", str(exe), str(C_HOST),
               "-static-libgcc"]
    else:
        exe = out_dir / f"c_host-{platform}"
        cmd = [*base, "-o", str(exe), str(C_HOST), "-ldl", "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    if platform == "win64":
        prefix = wineprefix or out_dir / "wine"
        env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(prefix.parent),
               "WINEPREFIX": str(prefix), "WINEDEBUG": "-all",
               # no Mono or Gecko installer dialogs when the prefix is made
               "WINEDLLOVERRIDES": "mscoree,mshtml="}
        return CrossHost(platform, exe, (_wine() or "wine",), env)
    if platform == "aarch64-linux" and host_platform() != "aarch64-linux":
        return CrossHost(platform, exe, ("qemu-aarch64", "-L", str(AARCH64_SYSROOT)), {})
    return CrossHost(platform, exe, (), {})


def host_system(sysfile: Path, host: CrossHost) -> Path:
    """The system file ``sysfile`` with its folders and series files named ``host``'s way
    (the last field of its ``fmu`` and ``series`` lines), beside it."""
    lines = []
    for line in sysfile.read_text().splitlines():
        if line.startswith("fmu "):
            head = line.split(" ", 4)
            line = " ".join([*head[:4], host.path(head[4])])
        elif line.startswith("series "):
            head = line.split(" ", 3)
            line = " ".join([*head[:3], host.path(head[3])])
        lines.append(line)
    out = sysfile.with_name(f"{sysfile.stem}-{host.platform}.txt")
    out.write_text("\n".join(lines) + "\n")
    return out


def stop_wine(host: CrossHost) -> None:
    """End the wineserver of ``host``'s prefix (the one this test session started)."""
    server = _wineserver()
    if host.platform == "win64" and server:
        subprocess.run([server, "-k"], env=host.env, capture_output=True, timeout=60)
