"""The compiled master (orchestrator/cosim/native_master.c) against the Python master, on
real native FMUs in real fmpy instances: traces equal bit for bit on the paper's loop and
on a per-vehicle fleet (with and without acoustic links, Gauss-Seidel and Jacobi), the
same error message when an FMU fails mid-run, a real SIGINT to a real `auv-cosim run`
keeping what was simulated, and which master ``auto`` picks."""
from __future__ import annotations

import dataclasses
import fcntl
import json
import os
import pty
import select
import shutil
import signal
import struct
import subprocess
import sys
import termios
import time

import numpy as np
import pytest

from orchestrator.cosim.instance import CosimError
from orchestrator.cosim.master import run_system
from orchestrator.interop.native import native_system
from orchestrator.running import build, scenario_system
from orchestrator.running.systems import make_setup
from orchestrator.scenario import load_scenario

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")


def _assert_identical(ref: dict, got: dict) -> None:
    """Same keys, shapes and every value bit for bit, and not a trivial trace."""
    assert set(ref) == set(got)
    for key in ref:
        assert ref[key].shape == got[key].shape, key
        assert np.array_equal(ref[key].view(np.uint64), got[key].view(np.uint64)), key
    assert any(float(np.ptp(v)) > 0 for v in ref.values())


@pytest.fixture(scope="module")
def paper_native(tmp_path_factory):
    sc = load_scenario("paper").with_run(T=20.0)
    tmp = tmp_path_factory.mktemp("paper_native")
    ns = native_system(scenario_system(sc), build(sc, tmp / "py"), tmp / "native")
    return sc, ns


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_the_compiled_master_equals_the_python_master_on_the_paper_loop(paper_native,
                                                                        coupling):
    sc, ns = paper_native
    ref, _, ref_info = run_system(ns.system, ns.fmus, sc.steps, coupling=coupling,
                                  master="python")
    got, _, info = run_system(ns.system, ns.fmus, sc.steps, coupling=coupling)
    assert ref_info["master"] == "python" and info["master"] == "native"
    assert info["master_reason"] == "every component is a native FMU"
    assert info["steps_done"] == sc.steps and info["calls_per_step"] == ref_info["calls_per_step"]
    _assert_identical(ref, got)


def _fleet(tmp_path_factory, links: bool):
    net = {"latency": 1.0, "period": 2.0, "loss": 0.2} if links else {}
    sc = load_scenario("formation-4").with_run(
        T=6.0, deployment="per-vehicle", architecture="distributed", fmus="native",
        network=net)
    setup = make_setup(sc, tmp_path_factory.mktemp("fleet_links" if links else "fleet"))
    method = setup.methods[0]
    return sc, setup.system(method, sc.seed), setup.fmus(method)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    return _fleet(tmp_path_factory, links=False)


@pytest.fixture(scope="module")
def fleet_links(tmp_path_factory):
    return _fleet(tmp_path_factory, links=True)


@pytest.mark.slow
@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_the_compiled_master_equals_the_python_master_on_a_per_vehicle_fleet(fleet, coupling):
    """formation-4, per-vehicle, distributed, every FMU native (13 FMUs)."""
    sc, system, fmus = fleet
    ref, _, _ = run_system(system, fmus, sc.steps, coupling=coupling, master="python")
    got, _, info = run_system(system, fmus, sc.steps, coupling=coupling)
    assert info["master"] == "native" and len(system.components) == 13
    _assert_identical(ref, got)


@pytest.mark.slow
@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_with_acoustic_links_auto_runs_native_and_equals_the_python_master(fleet_links,
                                                                          coupling):
    """formation-4 with links (latency 1 s, period 2 s, loss 0.2): the network FMUs are
    native too (AuvNetworkNative), so ``auto`` runs the compiled master, to the Python
    master's traces, the links' ages and counts included."""
    sc, system, fmus = fleet_links
    ref, _, info = run_system(system, fmus, sc.steps, coupling=coupling, master="python")
    got, _, info = run_system(system, fmus, sc.steps, coupling=coupling)
    assert info["master"] == "native" and info["master_reason"] == "every component is a " \
        "native FMU"
    assert any(c.fmu == "network" for c in system.components)
    _assert_identical(ref, got)
    age = [k for k in got if "age" in k]
    assert age and any(float(np.ptp(got[k])) > 0 for k in age)   # messages were heard


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
def test_an_fmu_error_mid_run_gives_the_python_masters_message(paper_native, coupling):
    """The plant's Ad[1,1] = 10 makes its state overflow after about 300 steps; the plant
    refuses to hand out an output that is no longer finite (fmi2GetReal: fmi2Error naming
    the output; with Jacobi coupling its own state overflows first and fmi2DoStep refuses
    the step, an fmi2Error): both masters raise the same CosimError (FMU, call, t, status,
    the FMU's message)."""
    sc, ns = paper_native
    comps = tuple(dataclasses.replace(c, parameters={**c.parameters, "Ad[1,1]": 10.0})
                  if c.name == "plant" else c for c in ns.system.components)
    bad = dataclasses.replace(ns.system, components=comps)
    messages = {}
    for master in ("python", "native"):
        with pytest.raises(CosimError) as err:
            run_system(bad, ns.fmus, sc.steps, coupling=coupling, master=master)
        messages[master] = str(err.value)
    assert messages["native"] == messages["python"]
    call = "fmi2GetReal" if coupling == "gauss-seidel" else "fmi2DoStep"
    assert messages["native"].startswith(f"plant FMU: {call} at t = ")
    assert "returned Error" in messages["native"]
    assert ("is not finite" if coupling == "gauss-seidel" else
            "state element 1 would become") in messages["native"]
    t = float(messages["native"].split("at t = ")[1].split(" s")[0])
    assert 1.0 < t < sc.T                                             # mid-run


def test_an_unknown_master_is_refused(paper_native):
    sc, ns = paper_native
    with pytest.raises(ValueError, match="master 'c' is not one of auto, native, python"):
        run_system(ns.system, ns.fmus, 2, master="c")


def _read_until(fd: int, proc: subprocess.Popen, needle: bytes, timeout: float) -> bytes:
    """Bytes read from ``fd`` until ``needle`` appears (or the process ends / timeout)."""
    out, deadline = b"", time.monotonic() + timeout
    while needle not in out and time.monotonic() < deadline and proc.poll() is None:
        if select.select([fd], [], [], 0.1)[0]:
            try:
                out += os.read(fd, 65536)
            except OSError:
                break
    return out


def _drain(fd: int) -> bytes:
    """What is left to read on ``fd`` (until end of file, or 0.5 s without data)."""
    out = b""
    while select.select([fd], [], [], 0.5)[0]:
        try:
            chunk = os.read(fd, 65536)
        except OSError:                  # the terminal's other end is closed
            break
        if not chunk:
            break
        out += chunk
    return out


@pytest.mark.parametrize("options, T", [(["--fmus", "native"], 3000.0),
                                        (["--master", "native"], 3000.0)],
                         ids=["native-fmus", "pythonfmu-fmus"])
@pytest.mark.slow
def test_a_sigint_stops_the_compiled_master_and_keeps_what_it_simulated(tmp_path, options, T):
    """A real `auv-cosim run` in the compiled master (300,000 steps, of native FMUs or of
    the pythonfmu FMUs, which take the GIL in each call; the bar shows after the first
    chunk of 16,384 steps), standard error on a terminal: once the progress bar shows, a
    SIGINT stops the loop before its next step;
    the .rrd holds the steps up to there, the summary says interrupted and which master
    ran, one line says what was kept, exit status 130."""
    from orchestrator.recording import read_rrd_scalars
    out = tmp_path / "run"
    master_fd, slave_fd = pty.openpty()
    fcntl.ioctl(slave_fd, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # tqdm draws
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", *options,
                             "--T", str(T), "--out", str(out)], stdout=subprocess.PIPE,
                            stderr=slave_fd)
    os.close(slave_fd)
    try:
        seen = _read_until(master_fd, proc, b"step/s", 240)     # tqdm's rate: in the loop
        assert b"step/s" in seen, seen.decode(errors="replace")
        proc.send_signal(signal.SIGINT)
        stdout, _ = proc.communicate(timeout=240)
        rest = _drain(master_fd)
    finally:
        proc.kill()
        os.close(master_fd)
    assert proc.returncode == 130, stdout
    text = (seen + rest).decode(errors="replace").replace("\r", "\n")
    lines = [ln for ln in text.splitlines() if ln.startswith("auv-cosim: interrupted")]
    assert len(lines) == 1 and lines[0].startswith("auv-cosim: interrupted by SIGINT at t = ")
    assert b"master: compiled (C) step loop" in stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["interrupted_by"] == "SIGINT"
    assert summary["master"] == {"kalman": "native"}
    reached, steps = summary["time_reached_s"], summary["rrd"]["recorded_steps"]
    assert 0 < reached < T and steps == round(reached / 0.01)
    assert f"{reached:.6g}" in lines[0]
    k, _, e1 = read_rrd_scalars(out / "paper.rrd")["error/1/kalman"]
    assert np.array_equal(k, np.arange(steps)) and np.all(np.isfinite(e1))


@pytest.mark.slow
def test_compare_over_seeds_gives_the_same_statistics_in_both_masters(tmp_path):
    """`compare --fmus native` over 3 seeds, once per master: every seed's cost rate is the
    same float and summary.json's ``master`` names the master that ran."""
    from orchestrator.cli import main
    summaries = {}
    for master in ("native", "python"):
        out = tmp_path / master
        assert main(["compare", "--fmus", "native", "--master", master, "--seeds", "0-2",
                     "--T", "20", "--methods", "kalman", "--quiet", "--out", str(out)]) == 0
        summaries[master] = json.loads((out / "summary.json").read_text())
        assert summaries[master]["master"] == {"kalman": master}
    per_seed = [s["methods"]["kalman"]["cost_rate"]["per_seed"] for s in summaries.values()]
    assert per_seed[0] == per_seed[1] and len(set(per_seed[0])) == 3


def test_a_hard_stop_waits_for_the_loop_before_the_fmus_are_freed(paper_native):
    """A KeyboardInterrupt in the waiting thread (a second signal) stops the compiled loop
    and waits for it: it propagates, and no loop thread is left calling freed FMUs."""
    import threading
    sc, ns = paper_native

    class Interrupting:
        def __init__(self) -> None:
            self.seen = 0

        def update(self, n: int) -> None:
            self.seen += n
            raise KeyboardInterrupt

    bar = Interrupting()
    with pytest.raises(KeyboardInterrupt):
        run_system(ns.system, ns.fmus, 200_000, progress=bar, master="native")
    assert 0 < bar.seen < 200_000
    assert not [t for t in threading.enumerate() if t.name == "auv-cosim compiled master"]


def test_without_a_compiler_auto_runs_python_and_native_is_refused(paper_native,
                                                                    monkeypatch):
    """No C compiler (CC names none) and no library loaded yet: ``auto`` runs the Python
    master and says why; ``native`` is refused in one line naming the master."""
    from orchestrator.cosim import native_master
    from orchestrator.cosim.native import NativeBuildError
    sc, ns = paper_native
    monkeypatch.setattr(native_master, "_LIBRARY", None)
    monkeypatch.setenv("CC", "no-such-compiler")
    _, _, info = run_system(ns.system, ns.fmus, 10)
    assert info["master"] == "python"
    assert info["master_reason"].startswith("the compiled master is not available: no C "
                                            "compiler: 'no-such-compiler'")
    with pytest.raises(NativeBuildError, match="^master native: no C compiler"):
        run_system(ns.system, ns.fmus, 10, master="native")
