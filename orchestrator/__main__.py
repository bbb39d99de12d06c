"""``python -m orchestrator`` is the ``auv-cosim`` command."""
import sys

from .cli import main

sys.exit(main())
