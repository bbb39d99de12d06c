"""Screenshot a .rrd in the real Rerun viewer, headless (how docs/images/*.png were made).

    python docs/images/screenshot.py RUN.rrd OUT.png [SIM_TIME_S or -] [WIDTH]

Needs a Vulkan driver: on Debian, `apt-get install mesa-vulkan-drivers libvulkan1` (the
software rasterizer lavapipe). The viewer is the `rerun` of this environment (put its
folder first on PATH). The PNG is scaled to WIDTH pixels (default 1456) and saved with a
reduced palette to stay small. The commands behind each image are in docs/recording.md.
"""
import sys
import time

import rerun.experimental as rx
from PIL import Image

rrd, png = sys.argv[1], sys.argv[2]
t = float(sys.argv[3]) if len(sys.argv) > 3 and sys.argv[3] not in ("", "-") else None
width = int(sys.argv[4]) if len(sys.argv) > 4 else 1456
viewer = rx.ViewerClient.spawn(headless=True, port=9911, hide_welcome_screen=True)
try:
    viewer.open(rrd)
    time.sleep(6)                       # let the viewer load and lay out
    if t is not None:
        viewer.set_time("sim_time", duration=t, play_state="paused")
        time.sleep(3)
    viewer.save_screenshot(png)
    time.sleep(2)
finally:
    viewer.quit()
img = Image.open(png).convert("RGB")
if img.width > width:
    img = img.resize((width, round(img.height * width / img.width)), Image.LANCZOS)
img.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(png, optimize=True)
