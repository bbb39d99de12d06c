"""What the traces mean: predictions and statistics, and the monolithic reference loop.

- :mod:`.prediction`: stationary RMS and cost from the discrete Lyapunov equation of the
  sampled closed loop; :mod:`.jacobi`: the same for the loop as libcosim couples it;
- :mod:`.summary`: statistics of traces over seeds, the statistics window;
- :mod:`.reference`: the same algorithm as one plain numpy loop (no FMI), for checks and
  benchmarks.
- :mod:`.acoustic`: the per-vehicle loop over acoustic links and its exact predictions.
"""
