"""Screenshot a headless Rerun viewer that a ``--live`` run streams to, mid-run (how
docs/images/live-viewer.png was made).

    python docs/images/live_screenshot.py OUT.png SECONDS -- RUN_ARGS...

Starts a headless viewer (Vulkan needed, as for docs/images/screenshot.py), runs
``auv-cosim run RUN_ARGS --live <its URL>``, takes the screenshot SECONDS of wall clock
after the run started (give ``--realtime`` so the run is still going), waits for the run
to end and scales the PNG as screenshot.py does.
"""
import subprocess
import sys
import time
from pathlib import Path

import rerun.experimental as rx
from PIL import Image

png, seconds = sys.argv[1], float(sys.argv[2])
args = sys.argv[sys.argv.index("--") + 1:]
rerun = Path(sys.executable).with_name("rerun")
viewer = rx.ViewerClient.spawn(headless=True, port=9912, hide_welcome_screen=True,
                               executable_path=str(rerun) if rerun.exists() else None)
try:
    run = subprocess.Popen([sys.executable, "-m", "orchestrator", "run", *args,
                            "--live", viewer.url])
    time.sleep(seconds)
    assert run.poll() is None, "the run ended before the screenshot: slow it (--realtime)"
    viewer.save_screenshot(png)
    time.sleep(2)
    print(f"screenshot at {seconds:g} s of wall clock; waiting for the run", flush=True)
    assert run.wait() == 0
finally:
    viewer.quit()
img = Image.open(png).convert("RGB")
if img.width > 1456:
    img = img.resize((1456, round(img.height * 1456 / img.width)), Image.LANCZOS)
img.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(png, optimize=True)
