"""The per-vehicle loop over acoustic links (plant_model.acoustic) and its exact predictions.

- :mod:`.message_form`: the loop cut at its messages (what each vehicle computes alone,
  what each sender transmits, how a received value enters its receiver);
- :mod:`.loop`: the networked loop, messages in flight and held as states (Z = [X; F; R]);
- :mod:`.prediction`: its exact second moment over a window, mean-square stability and the
  critical loss probability;
- :mod:`.blocks`: the window prediction kept in blocks, for loops beyond the dense size.

Import the modules themselves; this package imports none of them. See docs/network.md.
"""
