"""The master's chunked buffers (orchestrator/cosim/master.py, ``run_system(sink=...)``):
a run handed to a sink chunk by chunk, on buffers of one chunk reused, gives the whole
run's traces bit for bit, in the Python and the compiled master, Gauss-Seidel and Jacobi,
with uneven chunks and a chunk of one step; a sink that keeps nothing sees every step once,
in order; a stop mid-run hands on what ran."""
from __future__ import annotations

import numpy as np
import pytest

from orchestrator.cosim.master import run_system
from support.masters import on_master, paper_systems


class Gather:
    """A sink that copies every chunk (the test's witness)."""

    def __init__(self, chunk_steps: int):
        self.chunk_steps = chunk_steps
        self.parts: list[tuple[int, dict[str, np.ndarray]]] = []

    def take(self, k0: int, traces: dict[str, np.ndarray]) -> None:
        self.parts.append((k0, {k: v.copy() for k, v in traces.items()}))

    def joined(self) -> dict[str, np.ndarray]:
        keys = self.parts[0][1]
        return {k: np.concatenate([p[k] for _, p in self.parts]) for k in keys}


class Stopper:
    """A stop flag that turns true once the sink has seen ``after`` steps."""

    name = "SIGTERM"

    def __init__(self) -> None:
        self.on = False

    def __bool__(self) -> bool:
        return self.on


@pytest.fixture(scope="module")
def paper(tmp_path_factory):
    return paper_systems(tmp_path_factory.mktemp("chunks"), 6.0)


def _bits_equal(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and np.array_equal(a.view(np.uint64), b.view(np.uint64))


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("master", ["python", "native"])
@pytest.mark.parametrize("chunk", [1, 7, 64])
def test_a_chunked_run_gives_the_whole_runs_traces_bit_for_bit(paper, coupling, master,
                                                               chunk):
    sc = paper[0]
    system, fmus = on_master(paper, master)
    steps = sc.steps
    ref, _, _ = run_system(system, fmus, steps, coupling=coupling, master=master)
    sink = Gather(chunk)
    empty, _, info = run_system(system, fmus, steps, coupling=coupling, master=master,
                                sink=sink)
    assert empty == {} and info["steps_done"] == steps and info["master"] == master
    starts = [k0 for k0, _ in sink.parts]
    assert starts == list(range(0, steps, chunk))           # every step once, in order
    assert all(len(next(iter(p.values()))) <= chunk for _, p in sink.parts)
    got = sink.joined()
    assert set(got) == set(ref)
    for key in ref:
        assert _bits_equal(ref[key], got[key]), key
    assert any(float(np.ptp(v)) > 0 for v in ref.values())


@pytest.mark.parametrize("master", ["python", "native"])
def test_a_stop_hands_on_the_steps_that_ran(paper, master):
    sc = paper[0]
    system, fmus = on_master(paper, master)
    stop = Stopper()

    class StopAfterTwo(Gather):
        def take(self, k0, traces):
            super().take(k0, traces)
            if len(self.parts) == 2:
                stop.on = True

    sink = StopAfterTwo(10)
    ref, _, _ = run_system(system, fmus, sc.steps, master=master)
    _, _, info = run_system(system, fmus, sc.steps, master=master, sink=sink, stop=stop)
    assert info["steps_done"] == 20 and info["interrupted_by"] == "SIGTERM"
    got = sink.joined()
    for key in ref:
        assert _bits_equal(ref[key][:20], got[key]), key


class SaveAt:
    """Checkpoints due at one step; keeps the state (pickled and back: it goes to a file)."""

    def __init__(self, step: int):
        self.step, self.state = step, None

    def due(self, step: int) -> bool:
        return step == self.step

    def save(self, state) -> None:
        import pickle
        self.state = pickle.loads(pickle.dumps(state))


@pytest.mark.parametrize("coupling", ["gauss-seidel", "jacobi"])
@pytest.mark.parametrize("master", ["python", "native"])
def test_a_run_resumed_from_a_saved_state_continues_bit_for_bit(paper, coupling, master):
    sc = paper[0]
    system, fmus = on_master(paper, master)
    whole, save = Gather(50), SaveAt(250)
    run_system(system, fmus, sc.steps, coupling=coupling, master=master, sink=whole,
               checkpoints=save)
    assert save.state is not None and save.state.step == 250
    assert set(save.state.fmus) == {c.name for c in system.components}
    assert all(len(b) > 0 for b in save.state.fmus.values())
    assert (save.state.next_row is not None) == (coupling == "jacobi")
    tail = Gather(50)
    _, _, info = run_system(system, fmus, sc.steps, coupling=coupling, master=master,
                            sink=tail, start=save.state)
    assert [k0 for k0, _ in tail.parts] == list(range(250, sc.steps, 50))
    ref, got = whole.joined(), tail.joined()
    for key in ref:
        assert _bits_equal(ref[key][250:], got[key]), key
    # the noise went on: the resumed part is not a repeat of the start
    assert not np.array_equal(got["y"][:50], ref["y"][:50])


def test_a_state_of_another_system_is_refused_naming_the_components(paper):
    from orchestrator.cosim.master import CosimError, MasterState
    sc, system, fmus, _ = paper
    bad = MasterState(50, {"plant": b"x", "rudder": b"y"})
    with pytest.raises(CosimError, match="not in this system: rudder; without a saved state: "
                                         "controller, estimator"):
        run_system(system, fmus, sc.steps, sink=Gather(50), start=bad)
