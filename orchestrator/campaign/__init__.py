"""Campaigns: Monte Carlo runs and parameter sweeps on one machine or a Dask cluster.

- :mod:`.spec`: the campaign spec (TOML), validated, one-line errors naming the key;
- :mod:`.points`: the grid or list of design points, resolved scenarios, run keys;
- :mod:`.tasks`: one task = one point's batch of seeds, its design solved once;
- :mod:`.engine_numpy`: the closed loop vectorised over seeds (linear plants, perfect links);
- :mod:`.cluster`: Dask (a local cluster or ``--scheduler``): the only module importing Dask;
- :mod:`.results`: the output folder's lock, incremental rows, Parquet tables;
- :mod:`.aggregate`, :mod:`.plot`: means and confidence intervals against the prediction;
- :mod:`.runner`: ``auv-cosim campaign``.

Nothing here is imported by the other commands, and importing this package imports no Dask.
"""
