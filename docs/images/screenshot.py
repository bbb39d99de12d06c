"""Screenshot a .rrd in the real Rerun viewer, headless (how docs/images/*.png were made).

    python docs/images/screenshot.py RUN.rrd OUT.png [SIM_TIME_S]

Needs a Vulkan driver: on Debian, `apt-get install mesa-vulkan-drivers libvulkan1` (the
software rasterizer lavapipe). The viewer is the `rerun` of this environment (put its
folder first on PATH). Made for docs/images/paper-layout.png (`auv-cosim compare`, T = 300 s,
seed 0) and docs/images/fleet-layout.png (`auv-cosim compare --scenario formation-4 --T 300
--seeds 0`, at t = 150 s), then scaled to 1456 px wide.
"""
import sys
import time

import rerun.experimental as rx

rrd, png = sys.argv[1], sys.argv[2]
t = float(sys.argv[3]) if len(sys.argv) > 3 else None
viewer = rx.ViewerClient.spawn(headless=True, port=9911, hide_welcome_screen=True)
try:
    viewer.open(rrd)
    time.sleep(4)                       # let the viewer load and lay out
    if t is not None:
        viewer.set_time("sim_time", duration=t, play_state="paused")
        time.sleep(2)
    viewer.save_screenshot(png)
    time.sleep(1)
finally:
    viewer.quit()
