"""No code tests a vehicle model's name outside its own module and the registry: the rest
asks the registry entry (plant_model.vehicle_models)."""
from __future__ import annotations

import pytest

from plant_model.fleet_parameters import fleet_parameter_specs
from plant_model.linalg_checks import ModelError
from plant_model.vehicle_models import REGISTRY
from tests.support.name_tests import name_tests

#: the registry and the models' own modules
VEHICLE_MODULES = ("plant_model/vehicle_models.py", "plant_model/vehicles.py",
                   "plant_model/remus100/", "plant_model/vehicle_fmu.py",
                   "plant_model/vehicle_fmu_identification.py")


def test_no_vehicle_model_name_is_tested_outside_its_module_and_the_registry():
    found = name_tests(REGISTRY, VEHICLE_MODULES)
    assert not found, "model names tested outside the registry:\n" + "\n".join(found)


def test_the_name_scanner_finds_a_test_it_is_shown(tmp_path, monkeypatch):
    """The scanner is not vacuous: a comparison written in a package is found."""
    import tests.support.name_tests as nt
    pkg = tmp_path / "orchestrator"
    pkg.mkdir()
    (pkg / "x.py").write_text('if m == "remus100":\n    pass\nok = m in ("generic",)\n'
                              '# m == "remus100" in a comment is not a test\n')
    monkeypatch.setattr(nt, "ROOT", tmp_path)
    assert [f.split(":")[1] for f in nt.name_tests(["remus100", "generic"], ())] == ["1", "3"]


def test_a_vehicle_parameter_a_fleet_fmu_cannot_take_is_refused_in_one_line():
    spec = {"vehicles": [{"model": "remus100", "params": {"cruise_speed": 1.5}},
                         {"model": "remus100", "params": {"substep": 0.01}}],
            "graph": {"edges": [], "pinning": [], "coupling": [[0.0]]}, "leader": {}}
    with pytest.raises(ModelError) as err:
        fleet_parameter_specs(spec, "plant")
    msg = str(err.value)
    assert "\n" not in msg
    assert msg.startswith("vehicle 2: parameter 'substep' of the remus100 model")
    assert "mass, added_mass, time_constant, drag_coefficient, cruise_speed" in msg


def test_every_linear_model_documents_each_parameter_it_takes():
    for entry in REGISTRY.values():
        if not entry.nonlinear:
            assert set(entry.params) <= set(entry.param_docs), entry.name
            assert all(doc for _, doc in entry.param_docs.values())


def test_no_link_model_name_is_tested_outside_the_link_model_registry():
    from plant_model.acoustic.link_models import LINK_MODELS
    found = name_tests(LINK_MODELS, ("plant_model/acoustic/link_models.py",))
    assert not found, "link model names tested outside the registry:\n" + "\n".join(found)
