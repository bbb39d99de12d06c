"""Benchmarks: what the co-simulation costs, printed by ``auv-cosim bench``.

- :mod:`.paper`: the paper's run through the three FMUs against the monolithic numpy loop,
  generated grid fleets (``--fleet``), other tools on the same FMUs (``--tools``: libcosim,
  fmpy's simulate_ssp) and the command's start-up (``--startup``);
- :mod:`.per_vehicle`: the per-vehicle deployment against fleet size N (``--fleet ...
  --deployment per-vehicle``);
- :mod:`.native`: microseconds per step with native FMUs (``--native``), and the C host's
  system file;
- :mod:`.remus`: what the nonlinear REMUS 100 costs (``--remus``);
- :mod:`.campaign`: campaign throughput and the design cache's gain (``--campaign``).

Each module is imported by the command that runs it, when it runs: importing this package
imports none of them.
"""
