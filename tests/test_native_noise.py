"""The native FMUs' noise is numpy's (fmu_common/native/numpy_random.c): the C generator
draws numpy's standard normals bit for bit (SeedSequence, PCG64, ziggurat with its tail and
wedge), a native plant's xi is the pythonfmu plant's normal row, and so an all-native loop
equals the all-pythonfmu loop of the same seed to 1e-12 of each signal's scale, also when a
host sets another seed."""
from __future__ import annotations

import ctypes
import dataclasses
import shutil
import subprocess

import numpy as np
import pytest
from scipy.linalg import block_diag
from test_native import _assert_equal_traces, _native

from orchestrator.cosim.master import run_system
from orchestrator.cosim.native import CFLAGS, NATIVE_DIR
from orchestrator.scenario import load_scenario
from plant_model.discretization import discretize
from plant_model.native_plant import noise_map
from plant_model.plant import NoiseStream

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler (cc)")

#: numpy's ziggurat: |x| beyond this comes from the tail branch (idx == 0)
ZIGGURAT_NOR_R = 3.6541528853610087963519472518

HARNESS = r"""
#include <stdint.h>
#include "numpy_random.h"
void normals(const uint64_t *entropy, int n, double *out, long count, uint64_t *next) {
    NprPcg64 g;
    npr_seed(&g, entropy, n);
    for (long i = 0; i < count; i++) out[i] = npr_standard_normal(&g);
    *next = npr_next_uint64(&g);
}
"""


@pytest.fixture(scope="module", params=["int128", "portable"])
def harness(request, tmp_path_factory):
    """The generator of the native FMUs compiled with a tiny driver (the build's CFLAGS;
    ``portable``: the 128-bit product from 32-bit pieces, for compilers without __int128)."""
    tmp = tmp_path_factory.mktemp("npr")
    (tmp / "harness.c").write_text(HARNESS)
    lib = tmp / "harness.so"
    extra = ["-DNPR_NO_INT128"] if request.param == "portable" else []
    r = subprocess.run(["cc", *CFLAGS, *extra, f"-I{NATIVE_DIR}", "-o", str(lib),
                        str(tmp / "harness.c"), str(NATIVE_DIR / "numpy_random.c"), "-lm"],
                       capture_output=True, text=True)
    assert r.returncode == 0 and not r.stderr, r.stderr          # no warning either
    dll = ctypes.CDLL(str(lib))
    dll.normals.restype = None
    return dll


def _c_normals(dll, entropy, count):
    ent = np.array(entropy, dtype=np.uint64)
    out = np.empty(count)
    nxt = np.zeros(1, dtype=np.uint64)
    dll.normals(ent.ctypes.data_as(ctypes.c_void_p), ctypes.c_int(ent.size),
                out.ctypes.data_as(ctypes.c_void_p), ctypes.c_long(count),
                nxt.ctypes.data_as(ctypes.c_void_p))
    return out, int(nxt[0])


@pytest.mark.parametrize("entropy", [[0], [1], [12345], [2**31 - 1], [2**40 + 5],
                                     [7, 0], [7, 3], [2024, 12], [0, 0], [3, 1, 4, 1, 5]])
def test_the_c_generator_draws_numpys_normals_bit_for_bit(harness, entropy):
    """100,000 normals of default_rng(seed) or default_rng([seed, key]) (a two-word seed
    and a five-word list too): the same bits, and the generator has consumed exactly as many
    64-bit words as numpy's, so the tail (idx == 0) and the wedge rejections, which take
    extra words, are numpy's too; both occur in every run."""
    count = 100_000
    got, nxt = _c_normals(harness, entropy, count)
    arg = entropy[0] if len(entropy) == 1 else entropy
    bits = np.random.PCG64(arg)
    ref = np.random.Generator(bits).standard_normal(count)
    assert np.array_equal(got.view(np.uint64), ref.view(np.uint64))
    assert nxt == int(bits.random_raw())
    assert np.array_equal(ref, np.random.default_rng(arg).standard_normal((count // 5, 5))
                          .reshape(-1))                    # rows: the same stream
    raw = np.random.PCG64(arg).random_raw(count + count // 20)
    used = int(np.flatnonzero(raw == np.uint64(nxt))[0])   # words the normals took
    tails = int(np.sum(np.abs(ref) > ZIGGURAT_NOR_R))
    assert tails >= 1                                      # each took 2 extra words or more
    assert used - count > 2 * tails + 100                  # the rest: wedge tests


@pytest.mark.parametrize("scenario", ["paper", "formation-4"])
def test_the_native_noise_map_colours_numpys_rows_like_the_plant(scenario):
    """xi is the streams' standard normal rows one after the other and P xi the plant's
    noise row (P P' = blkdiag(Qd, Rd)): the paper's single generator, formation-4's five
    streams (vehicles [seed, 1..4], the leader [seed, 0])."""
    sc = load_scenario(scenario)
    model = discretize(sc.system, sc.h)
    P, streams = noise_map(model)
    assert len(streams) == (1 if scenario == "paper" else 5)
    full = block_diag(model.Qd, model.Rd)
    assert np.allclose(P @ P.T, full, rtol=0, atol=1e-12 * np.abs(full).max())
    steps, seed = 300, 11
    xi = np.hstack([np.random.default_rng(seed if key is None else [seed, key])
                    .standard_normal((steps, count)) for key, count in streams])
    ref = NoiseStream.all_rows(model, seed, steps)
    assert np.abs(xi @ P.T - ref).max() <= 1e-14 * np.abs(ref).max()


def _with_seed(system, seed):
    """Every noisy component (plant, vehicle, leader) with the seed a host sets."""
    return dataclasses.replace(system, components=tuple(
        dataclasses.replace(c, parameters={**c.parameters, "seed": seed})
        if c.fmu in ("plant", "vehicle", "leader") else c for c in system.components))


def _assert_native_equals_pythonfmu(sc, tmp_path, kinds=None, seed=None):
    system, py, ns = _native(sc, tmp_path, kinds)
    if seed is not None:
        system, native = _with_seed(system, seed), _with_seed(ns.system, seed)
    else:
        native = ns.system
    ref, _, _ = run_system(system, py, sc.steps)
    got, _, _ = run_system(native, ns.fmus, sc.steps)
    _assert_equal_traces(ref, got)
    return ref, ns


@pytest.mark.slow
def test_the_all_native_paper_loop_equals_the_pythonfmu_loop(tmp_path):
    """The paper's loop, every FMU native (the plant too), equals the all-pythonfmu loop to
    1e-12 of each signal's scale; with the plant's seed set by the host (7) as well."""
    sc = load_scenario("paper").with_run(T=20.0)
    ref, ns = _assert_native_equals_pythonfmu(sc, tmp_path / "a")
    assert ns.fmus["plant"].name == "AuvPlantNative.fmu"
    assert np.std(ref["y"][:, 0] - ref["x"][:, 0]) > 0       # a noisy loop
    other, _ = _assert_native_equals_pythonfmu(sc, tmp_path / "b", seed=7)
    assert not np.array_equal(other["y"], ref["y"])


@pytest.mark.slow
@pytest.mark.parametrize("architecture, seed", [("distributed", None), ("centralized", 5)])
def test_the_all_native_per_vehicle_loop_equals_the_pythonfmu_loop(tmp_path, architecture,
                                                                     seed):
    """formation-4 per vehicle, every FMU native (the leader and the vehicles drawing
    [seed, 0] and [seed, i]), equals the pythonfmu loop to 1e-12; the centralized case with
    a host-set seed."""
    sc = load_scenario("formation-4").with_run(T=20.0, deployment="per-vehicle",
                                               architecture=architecture)
    _, ns = _assert_native_equals_pythonfmu(sc, tmp_path, seed=seed)
    assert [ns.forms[f"vehicle_{i}"].stream for i in range(1, 5)] == [1, 2, 3, 4]
    assert ns.forms["leader"].stream == 0


@pytest.mark.slow
def test_the_native_stacked_fleet_plant_draws_its_five_streams(tmp_path):
    """formation-4 stacked: the native plant's five streams with the pythonfmu estimator
    and controller equal the all-pythonfmu loop to 1e-12."""
    sc = load_scenario("formation-4").with_run(T=20.0)
    _, ns = _assert_native_equals_pythonfmu(sc, tmp_path, ("plant",))
    assert [k for k, _ in ns.forms["plant"].noise_streams] == [1, 2, 3, 4, 0]
    assert ns.forms["plant"].stream is None
