"""A real ``auv-cosim run`` killed with SIGKILL after its first checkpoint (the resume
tests: tests/test_resume.py, tests/test_live.py)."""
from __future__ import annotations

import pickle
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

from orchestrator.running.checkpoint import CHECKPOINT_DIR, CHECKPOINT_FILE
from support.outputs import staging_folders


def killed_after_a_checkpoint(out: Path, args: list[str], seed: int) -> int:
    """Start ``run`` into ``out`` checkpointing at every chunk, SIGKILL it a random moment
    (0-0.4 s) after its first checkpoint; the step it was killed after."""
    proc = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", *args, "--quiet",
                             "--out", str(out), "--checkpoint-every", "0.001"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while not [s for s in staging_folders(out)
                   if (s / CHECKPOINT_DIR / CHECKPOINT_FILE).exists()]:
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline
            time.sleep(0.02)
        time.sleep(random.Random(seed).uniform(0.0, 0.4))
        assert proc.poll() is None, "the run ended before it could be killed"
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == -signal.SIGKILL
    assert not (out / "summary.json").exists()            # nothing finished under OUT
    (staging,) = staging_folders(out)
    ck = pickle.loads((staging / CHECKPOINT_DIR / CHECKPOINT_FILE).read_bytes())
    return ck.master.step
