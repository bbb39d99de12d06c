"""plant_model.vehicle_models: the registry of vehicle models and what it says about each."""
from __future__ import annotations

import pytest

from orchestrator.cosim.build import FMU_KINDS
from plant_model.linalg_checks import ModelError
from plant_model.vehicle_models import (
    LAYOUTS,
    REGISTRY,
    VEHICLE_MODELS,
    family_of,
    find,
    get,
    make_vehicle,
    plants_of,
    vehicle_of,
)


def test_one_entry_per_model_name_with_its_facts():
    assert VEHICLE_MODELS == ("remus100", "remus100-6dof", "remus100-fitted", "generic",
                              "remus100-6dof-guided", "fmu")
    assert [n for n in VEHICLE_MODELS if get(n).nonlinear] == ["remus100-6dof",
                                                               "remus100-6dof-guided", "fmu"]
    six = get("remus100-6dof")
    assert (six.fmu_kind, six.native, six.design, six.family, six.stack) == (
        "remus6dof", False, "remus100", "remus100", ())
    guided = get("remus100-6dof-guided")
    assert (guided.fmu_kind, guided.native, guided.design, guided.family, guided.stack,
            guided.variant_of, guided.params) == (
        "remus6dof_actuated", False, "remus100", "remus100", ("guidance", "autopilot"),
        "remus100-6dof", six.params)
    assert vehicle_of("remus100-6dof-guided") == "remus100-6dof" == vehicle_of("remus100-6dof")
    assert all(k in FMU_KINDS for e in REGISTRY.values() for k in e.stack)
    assert {get(n).fmu_kind for n in ("remus100", "remus100-fitted", "generic")} == {"vehicle"}
    assert family_of("remus100-fitted") == "remus100" and family_of("generic") == "generic"
    assert [n for n in VEHICLE_MODELS if get(n).layout == "ned"] == [
        "remus100", "remus100-6dof", "remus100-fitted", "remus100-6dof-guided", "fmu"]
    assert get("remus100").params == ("mass", "added_mass", "time_constant",
                                      "drag_coefficient", "cruise_speed")
    assert get("remus100-fitted").params == ()
    assert {"cruise_speed", "design", "substep", "autopilot", "r_g", "L"} <= set(six.params)
    for entry in REGISTRY.values():
        assert entry.layout in LAYOUTS and entry.fmu_kind in FMU_KINDS and entry.doc


def test_plants_of_a_family_are_its_linear_design_model_then_the_nonlinear_one():
    # remus100-6dof-guided flies remus100-6dof's vehicle: not a plant of its own
    assert plants_of("remus100") == ("remus100", "remus100-6dof")
    assert plants_of("generic") == ()


def test_unknown_names():
    assert find("nautilus") is None and find(None) is None and family_of("nautilus") is None
    with pytest.raises(ModelError, match="unknown vehicle model 'nautilus'; known models: "
                                         "remus100, remus100-6dof, remus100-fitted, generic"):
        get("nautilus")


def test_explicit_params_build_the_same_model_again():
    for name, params in (("remus100", {"cruise_speed": 1.5}), ("remus100-fitted", {}),
                         ("remus100-6dof", {"cruise_speed": 1.2, "L": 1.7}),
                         ("remus100-6dof-guided", {"cruise_speed": 1.2, "L": 1.7}),
                         ("generic", {"A": [[0.0]], "B1": [[1.0]], "B2": [[1.0]],
                                      "C": [[1.0]]})):
        entry = get(name)
        model = make_vehicle(name, params, "vehicle 1")
        explicit = entry.explicit_params(model)
        assert set(explicit) <= set(entry.params)
        again = make_vehicle(name, explicit, "vehicle 1")
        assert (again.A == model.A).all() and (again.B1 == model.B1).all()
        assert entry.explicit_params(again) == explicit
