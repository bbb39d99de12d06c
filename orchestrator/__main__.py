"""``python -m orchestrator`` is the ``auv-cosim`` command."""
from .cli import console

console()
