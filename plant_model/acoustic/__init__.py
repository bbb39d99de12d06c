"""The acoustic network between vehicles: links, their settings, a switching schedule, an inbox.

- :mod:`.base`: the checks the others share (a number, a vehicle or "leader", whole steps);
- :mod:`.links`: one directed link (:class:`~.links.LinkTiming`,
  :class:`~.links.LinkChannel`: schedule, latency, loss, held or propagated receiver);
- :mod:`.schedule`: a switching topology, graphs with the times they take over;
- :mod:`.settings`: a fleet's ``[network]`` table (``RECEIVERS``, ``resolve_links``,
  ``check_network``);
- :mod:`.inbox`: one receiving vehicle's links stepped together;
- ``auv_network_slave.py``: the AuvNetwork FMU's slave (one per receiving vehicle).

Import the modules themselves; this package imports none of them. See docs/network.md.
"""
