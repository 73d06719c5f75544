"""The AR layer loads the overlay's kernels before its first frame (``ptam.ar.kernel_warm_up``)."""

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# In a fresh process, so that no other test has loaded a kernel: the AR layer is built (which warms the kernels),
# then every scene is drawn over grey and colour frames from poses all round the plane. Printed: the kernels'
# compiled signatures after the layer was built, and the ones the frames added.
_SCRIPT = """
import json
import numpy as np
from numba.core.registry import CPUDispatcher
import ptam.ar.raster_kernels as rk
from ptam.ar import ArLayer, Augmenter
from ptam.config import load_config
from ptam.geometry import se3, so3
from ptam.synthetic import load_scene

def signatures():
    return {k: [str(s) for s in v.signatures] for k, v in vars(rk).items() if isinstance(v, CPUDispatcher)}

cfg = load_config()
camera = load_scene("two_wall_short").camera
layer = ArLayer(camera, cfg, "eyes")
layer.close()
before = signatures()
rng = np.random.default_rng(0)
W, H = camera.size
for name in ("eyes", "game", "grid"):
    aug = Augmenter(camera, cfg, name)
    for i in range(30):
        centre = np.array([*rng.uniform(-0.3, 0.3, 2), rng.uniform(0.2, 1.0)])
        z = -centre / np.linalg.norm(centre) + rng.normal(0, 0.1, 3)  # looking about at the origin
        z /= np.linalg.norm(z)
        x = np.cross([0.0, 1.0, 0.0], z)
        x /= np.linalg.norm(x)
        R_wc = np.stack([x, np.cross(z, x), z], axis=1)
        T_cw = se3.inv(se3.from_Rt(R_wc, centre))
        image = rng.integers(0, 256, (H, W, 3) if i % 2 else (H, W), dtype=np.uint8)
        aug.augment(image, T_cw, i / 30.0, grey_ok=True)
after = signatures()
print(json.dumps({"before": before, "added": {k: sorted(set(after[k]) - set(before[k])) for k in after}}))
"""


def test_the_layer_loads_every_overlay_kernel_before_its_first_frame():
    out = subprocess.run([sys.executable, "-c", _SCRIPT], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout.strip().splitlines()[-1])
    loaded = [k for k, sigs in res["before"].items() if sigs]
    assert {
        "rasterise_polylines",
        "blend_coverage",
        "draw_spheres",
        "draw_decals",
        "outline_boxes",
    } <= set(loaded)
    assert {k: v for k, v in res["added"].items() if v} == {}
