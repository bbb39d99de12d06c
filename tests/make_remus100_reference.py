"""Run the published REMUS 100 (T. I. Fossen's Python Vehicle Simulator) through the
manoeuvres of tests/remus100_manoeuvres.py and write its figures to
tests/data/remus100_reference.json, which tests/test_remus100_published.py compares with.

    python tests/make_remus100_reference.py /path/to/PythonVehicleSimulator

The reference integrates with forward Euler (its ``dynamics`` and ``gnc.attitudeEuler``);
it runs here at 0.005 s, where its figures have converged to the digits the tests use.
It needs only numpy (the package's plotting modules are not imported).
"""
from __future__ import annotations

import json
import subprocess
import sys
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from remus100_manoeuvres import manoeuvre_figures

OUT = Path(__file__).parent / "data" / "remus100_reference.json"


def main(root: str) -> None:
    src = Path(root) / "src"
    sys.path.insert(0, str(src))
    # import the two modules without the package's __init__ (it imports matplotlib)
    pkg = types.ModuleType("python_vehicle_simulator")
    pkg.__path__ = [str(src / "python_vehicle_simulator")]
    lib = types.ModuleType("python_vehicle_simulator.lib")
    lib.__path__ = [str(src / "python_vehicle_simulator" / "lib")]
    sys.modules.update({"python_vehicle_simulator": pkg, "python_vehicle_simulator.lib": lib})
    import importlib.util

    def load(name: str, path: Path) -> types.ModuleType:
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        spec.loader.exec_module(mod)
        return mod

    base = src / "python_vehicle_simulator"
    gnc = load("python_vehicle_simulator.lib.gnc", base / "lib" / "gnc.py")
    load("python_vehicle_simulator.lib.control", base / "lib" / "control.py")
    remus = load("remus100_reference", base / "vehicles" / "remus100.py")
    vehicle = remus.remus100("stepInput")

    def step(x: np.ndarray, cmd: np.ndarray, dt: float) -> np.ndarray:
        eta, nu, act = x[:6].copy(), x[6:12].copy(), x[12:].copy()
        nu, act = vehicle.dynamics(eta, nu, act, cmd, dt)
        eta = gnc.attitudeEuler(eta, nu, dt)
        return np.concatenate([eta, nu, act])

    commit = subprocess.run(["git", "-C", root, "log", "-1", "--format=%H %cs", "--",
                             "src/python_vehicle_simulator/vehicles/remus100.py"],
                            capture_output=True, text=True).stdout.split()
    figures = manoeuvre_figures(step, 0.005, 0.005)
    OUT.write_text(json.dumps({
        "source": "T. I. Fossen, Python Vehicle Simulator, "
                  "src/python_vehicle_simulator/vehicles/remus100.py and lib/gnc.py",
        "repository": "https://github.com/cybergalactic/PythonVehicleSimulator",
        "remus100_commit": commit[0] if commit else None,
        "remus100_date": commit[1] if len(commit) > 1 else None,
        "integration": "forward Euler, 0.005 s (the reference's own scheme)",
        "figures": {k: round(v, 6) for k, v in figures.items()}}, indent=2) + "\n")
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main(sys.argv[1])
