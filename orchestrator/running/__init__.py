"""Running systems: the one run step (:mod:`.setup`: a :class:`RunSetup` per scenario and its
``run`` of one method and seed), the scenario-to-FMU mapping (:mod:`.fmus`), ``run`` and
``compare`` (:mod:`.compare`), the seed workers (:mod:`.seeds`), the per-vehicle deployment
(:mod:`.per_vehicle`) and its acoustic links (:mod:`.network`), and the studies built on
them: the plants compared (:mod:`.plants`) and the envelope (:mod:`.envelope`)."""
from .compare import simulate
from .fmus import fleet_layout, record_stride, scenario_config, write_fmu_readme
from .setup import Method, Predictions, RunSetup, method_list
from .systems import build, check_memory, make_setup, scenario_system

__all__ = ["Method", "Predictions", "RunSetup", "build", "check_memory", "fleet_layout",
           "make_setup", "method_list", "record_stride", "scenario_config", "scenario_system",
           "simulate", "write_fmu_readme"]
