"""``python -m orchestrator.cli`` is the ``auv-cosim`` command."""
from . import console

console()
