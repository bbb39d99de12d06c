"""Co-simulation: FMU build, the system description, the fmpy master.

- :mod:`.build`: the three FMUs (pythonfmu) and their completed modelDescription;
- :mod:`.system`: :class:`SystemDescription`, the single source of a system's wiring;
- :mod:`.checks`: the wiring against the FMUs' variables (used by the master and exports);
- :mod:`.instance`: one FMU instance on fmpy with raw FMI entry points;
- :mod:`.master`: the fixed-step master (Gauss-Seidel or Jacobi) driven by a description.
"""
