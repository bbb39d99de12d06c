"""consensus = "protocol": the consensus protocol of eq. 1 as a force the controller applies
(the plant keeps only the vehicles' physics), against the paper's in-plant model."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import block_diag

from controller_fmu.regulator import tracking_law
from estimator_fmu.registry import make_estimator
from orchestrator.analysis.prediction import predict_stationary
from orchestrator.analysis.reference import run_monolithic
from orchestrator.cosim.build import build_fmus
from orchestrator.running import scenario_config
from orchestrator.scenario import SCENARIO_DIR, ScenarioError, load_scenario
from plant_model.discretization import discretize
from plant_model.fleet import ConsensusProtocol
from support.loop import run_cosimulation


def _scenario(tmp_path, consensus="protocol", text=None):
    text = text or (SCENARIO_DIR / "formation-4.toml").read_text()
    text = text.replace("[graph]", f'[graph]\nconsensus = "{consensus}"', 1)
    path = tmp_path / f"f4-{consensus}.toml"
    path.write_text(text)
    return load_scenario(path)


@pytest.fixture(scope="module")
def both(tmp_path_factory):
    d = tmp_path_factory.mktemp("protocol")
    default = load_scenario("formation-4")                  # the protocol form is the default
    assert default.fleet.consensus == "protocol"
    return _scenario(d, "in-plant"), default


def test_the_protocol_force_reproduces_the_in_plant_terms(both):
    """B1 Kc = [-(L + G) kron Gamma, 0, Bz] and A_physics = A_in_plant + (L + G) kron Gamma,
    with Kc computed here independently (least squares per vehicle)."""
    inplant, proto = both
    sp, si = proto.system, inplant.system
    p = si.meta.get("consensus")
    assert p is None
    c = sp.meta["consensus"]
    assert isinstance(c, ConsensusProtocol)
    np.testing.assert_array_equal(c.design.A, si.A)
    spec = proto.fleet.spec
    models = proto.fleet.models
    LG = proto.fleet.graph.consensus_matrix()
    Gam = np.asarray(spec["graph"]["coupling"], dtype=float)
    coupled = np.kron(LG, Gam)
    np.testing.assert_allclose(sp.A, block_diag(*[m.A for m in models]), atol=1e-15)
    np.testing.assert_allclose(sp.A - coupled, si.A, atol=1e-12)
    assert not sp.Bz.any()
    n, r = si.n, si.r
    target = np.zeros((n, c.gain.shape[1]))
    target[:, :n] = -coupled
    target[:, n + r:] = si.Bz
    np.testing.assert_allclose(sp.B1 @ c.gain, target, atol=1e-12)
    lstsq = np.linalg.lstsq(sp.B1, target, rcond=None)[0]
    np.testing.assert_allclose(c.gain, lstsq, atol=1e-10)
    # the law: designed on the in-plant system, plus the protocol force
    Kd = tracking_law(si, "lq").Ks
    np.testing.assert_allclose(tracking_law(sp, "lq").Ks, Kd - lstsq, atol=1e-10)
    assert not tracking_law(sp, "lq").Ks.flags.writeable


def test_the_two_forms_differ_by_order_h(both):
    """Same design, same cost weights: the tracking error of the two sampled loops differs by
    O(h) (halving h halves the difference); the protocol form also pays R on the consensus
    force, which the in-plant form treats as physics."""
    diffs, costs = [], []
    for h in (0.02, 0.01, 0.005):
        preds = []
        for sc in both:
            m = discretize(sc.system, h)
            est = make_estimator(sc.system, m, "ideal")
            preds.append(predict_stationary(sc.system, m, est, tracking_law(sc.system).Ks))
        diffs.append(np.max(np.abs(np.subtract(preds[0].rms_e, preds[1].rms_e))))
        costs.append((preds[0].cost_rate, preds[1].cost_rate))
    assert 1.8 < diffs[0] / diffs[1] < 2.2 and 1.8 < diffs[1] / diffs[2] < 2.2, diffs
    assert diffs[1] < 1e-5
    assert all(b > a for a, b in costs)                         # the force costs something


def test_fmus_reproduce_the_monolithic_protocol_loop(both, tmp_path):
    """The three FMUs built for the protocol form (plant without the coupling, controller
    adding the force) against the monolithic numpy loop of the same sampled system."""
    _, proto = both
    cfg = scenario_config(proto)
    fmus = build_fmus(cfg, tmp_path / "fmus")
    for mode in ("ideal", "kalman"):
        res = run_cosimulation(fmus, cfg, mode=mode, seed=3, steps=400)
        ref = run_monolithic(proto.system, proto.h, mode, 3, 400, tracking=proto.tracking)
        for key in ("x", "u", "e", "xhat"):
            np.testing.assert_allclose(res.traces[key], ref[key], rtol=1e-9, atol=1e-9,
                                       err_msg=f"{mode} {key}")


def test_an_unreachable_coupling_is_refused_naming_the_rows(tmp_path):
    text = (SCENARIO_DIR / "formation-4.toml").read_text()
    start = text.index("coupling = [")
    end = text.index("]\n\n", start) + 1
    identity = [[1.0 if a == b else 0.0 for b in range(6)] for a in range(6)]
    text = text[:start] + f"coupling = {identity}" + text[end:]
    _scenario(tmp_path, "in-plant", text)                       # physics may do anything
    with pytest.raises(ScenarioError, match="rows for n, e, d cannot be produced by any force"):
        _scenario(tmp_path, "protocol", text)


def test_an_unknown_form_is_one_line(tmp_path):
    with pytest.raises(ScenarioError, match=r"\[graph\] consensus .*is unknown; expected one of "
                                            "in-plant, protocol"):
        _scenario(tmp_path, "telepathy")
