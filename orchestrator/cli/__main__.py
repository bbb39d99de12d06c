"""``python -m orchestrator.cli`` is the ``auv-cosim`` command."""
from .launch import console

console()
