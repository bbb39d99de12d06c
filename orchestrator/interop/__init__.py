"""Other tools' formats, all written from one :class:`~orchestrator.cosim.system.SystemDescription`.

- :mod:`.common`: the export error, value text, unit elements, the wiring check;
- :mod:`.osp`: Open Simulation Platform system (OspSystemStructure.xml, OspModelDescription);
- :mod:`.libcosim`: runs an OSP system in libcosim (libcosimpy);
- :mod:`.ssp`: SSP 1.0 archive (SystemStructure.ssd, parameter sets), fmpy's simulate_ssp;
- :mod:`.crosscheck`: FMI cross-check reference files of each FMU, cut out of the loop.
"""
