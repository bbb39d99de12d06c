"""``python -m orchestrator`` is the ``auv-cosim`` command."""
from .cli.launch import console

console()
