"""``python -m orchestrator`` is the ``auv-cosim`` command."""
from .launch import console

console()
