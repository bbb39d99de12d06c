"""Design points: grid and list expansion, resolution to scenarios (vehicle count through
the fleet generator), invalid points kept with their error, run keys."""
from __future__ import annotations

from orchestrator.campaign.points import expand_points, resolve_point, resolve_points, run_key
from orchestrator.campaign.spec import load_spec

VER = {"numpy": "2.0", "auv-cosim": "0.1.0"}


def _spec(tmp_path, text):
    p = tmp_path / "spec.toml"
    p.write_text(text)
    return load_spec(p)


def test_full_grid_then_list_crossed_with_grid(tmp_path):
    spec, _, base, where = _spec(tmp_path, """
base = "paper"
[sweep]
"simulation.estimator" = ["kalman", "classical", "ideal"]
"simulation.T" = [5.0, 10.0]
""")
    pts = expand_points(spec)
    assert len(pts) == 6
    assert pts[0] == {"simulation.estimator": "kalman", "simulation.T": 5.0}
    assert pts[1] == {"simulation.estimator": "kalman", "simulation.T": 10.0}
    spec, _, base, where = _spec(tmp_path, """
base = "paper"
[[points]]
"simulation.estimator" = "kalman"
"noise.V_y" = 0.5
[[points]]
"simulation.estimator" = "ideal"
[sweep]
"simulation.T" = [5.0, 10.0]
""")
    pts = expand_points(spec)
    assert pts == [{"simulation.estimator": "kalman", "noise.V_y": 0.5, "simulation.T": 5.0},
                   {"simulation.estimator": "kalman", "noise.V_y": 0.5, "simulation.T": 10.0},
                   {"simulation.estimator": "ideal", "simulation.T": 5.0},
                   {"simulation.estimator": "ideal", "simulation.T": 10.0}]
    resolved = resolve_points(spec, base, where)
    sc = resolved[0].scenario
    assert sc.estimator == "kalman" and sc.T == 5.0 and sc.system.V_y[0, 0] == 0.5
    assert resolved[3].scenario.estimator == "ideal" and resolved[3].scenario.system.V_y[0, 0] == 2


def test_vehicle_count_follows_the_generator(tmp_path):
    spec, _, base, where = _spec(tmp_path, 'base = "formation-4"\n[sweep]\n'
                                           '"vehicles.count" = [2, 6]\n"simulation.T" = [1.0]\n')
    small, large = resolve_points(spec, base, where)
    assert small.error is None and large.error is None
    assert small.scenario.system.n == 2 * 6 and large.scenario.system.n == 6 * 6
    assert large.scenario.fleet is not None
    assert base["vehicles"]["count"] == 4             # the base is not changed


def test_an_invalid_point_keeps_its_error(tmp_path):
    spec, _, base, where = _spec(tmp_path, 'base = "paper"\n[sweep]\n"simulation.h" = [0.01, -1.0]\n')
    good, bad = resolve_points(spec, base, where)
    assert good.error is None and bad.scenario is None
    assert "simulation.h = -1.0" in bad.error and "[simulation] h" in bad.error
    assert "\n" not in bad.error


def test_run_keys(tmp_path):
    spec, _, base, where = _spec(tmp_path, 'base = "paper"\n[sweep]\n"simulation.T" = [5.0, 6.0]\n')
    a, b = resolve_points(spec, base, where)
    a2 = resolve_point(0, {"simulation.T": 5.0}, base, where)
    assert run_key(a, 0, "fmu", VER) == run_key(a2, 0, "fmu", VER)          # stable
    keys = {run_key(a, 0, "fmu", VER), run_key(a, 1, "fmu", VER), run_key(b, 0, "fmu", VER),
            run_key(a, 0, "numpy", VER), run_key(a, 0, "fmu", dict(VER, numpy="2.1")),
            run_key(a, 0, "fmu", VER, role="check")}
    assert len(keys) == 6                                                   # all differ
    # the same scenario reached by another key is the same run
    same = resolve_point(5, {"simulation.T": 5.0, "simulation.estimator": "kalman"}, base, where)
    assert run_key(same, 0, "fmu", VER) == run_key(a, 0, "fmu", VER)



def test_the_run_key_holds_the_noise_stream(tmp_path):
    """Rows of noise stream 1 (machine-dependent factors) never mix with stream 2's: the
    versions a run key is made of carry the stream."""
    from orchestrator.analysis.summary import versions
    from plant_model.noise_factor import NOISE_STREAM
    spec, _, base, where = _spec(tmp_path, 'base = "paper"\n')
    (pt,) = resolve_points(spec, base, where)
    ver = versions()
    assert ver["noise_stream"] == str(NOISE_STREAM) == "2"
    assert run_key(pt, 0, "fmu", ver) != run_key(pt, 0, "fmu", dict(ver, noise_stream="1"))
