"""The kernel rehearsal before a live source starts (``ptam.system.warm_up``, ``System._rehearse``).

Its synthetic slide is tracked as its geometry says, takes the pipeline through keyframes, edgelets and bundle
adjustment, an async start loads the mapper's kernels before the first frame, and the rehearsal's own log lines
stay out of the user's log (one line says why the start waits when the kernels are being compiled).
"""

import logging
import subprocess
import sys
import time

import numpy as np
import pytest

from ptam.camera.fov import FovCamera
from ptam.camera.pinhole import PinholeCamera
from ptam.config import load_config
from ptam.eval.ate import ate
from ptam.system import System, core, warm_up
from ptam.system.warm_up import _FPS, _STEP_M, rehearsal_frames, rehearsal_log

CAMERAS = {
    "pinhole": PinholeCamera(640, 480, 500.0, 500.0, 319.5, 239.5),
    "fov": FovCamera(640, 480, 384.0, 384.0, 319.5, 239.5, 0.9),  # PTAM's lens model, two_wall's camera
}
# Kernels only the mapper reaches (bundle adjustment, the edgelet job, the epipolar searches) and the tracker's
# edgelet search: what a live session used to compile or load while frames arrived.
MAPPER_KERNELS = [
    "ptam.mapping.bundle_schur_kernels.ba_schur",
    "ptam.mapping.bundle_structure_kernels.landmark_layout",
    "ptam.mapping.bundle_edgelet_kernels.ba_edgelet_setup",
    "ptam.mapping.bundle_edgelet_kernels.ba_edgelet_linearise_at",
    "ptam.mapping.bundle_edgelet_kernels.ba_edgelet_trial",
    "ptam.mapping.bundle_solve_kernels.ba_gauged_solve",
    "ptam.mapping.bundle_schur_kernels.ba_edgelet_schur",
    "ptam.mapping.bundle_solve_kernels.ba_envelope_solve",
    "ptam.mapping.epipolar_kernels.epipolar_search",
    "ptam.mapping.edgelet_epipolar_kernels.curve_hits",
    "ptam.mapping.edgelet_cull_kernels.polarity_cull",
    "ptam.mapping.edgelet_epipolar_kernels.curve_vertices",
    "ptam.mapping.edgelet_aperture_kernels.aperture_free",
    "ptam.edgelet.edgel_linker_kernels.link_edgels",
    "ptam.edgelet.edgelet_refine_kernels.refine_frames",
    "ptam.edgelet.sawtooth_kernels.sawtooth_search",
    "ptam.edgelet.sawtooth_kernels.visibility_table",
    "ptam.edgelet.edgelet_projection_kernels.edgelet_projection",
    "ptam.edgelet.edgelet_triangulation_kernels.triangulate_lines",
    "ptam.tracking.pose_kernels.pose_irls_edgelets",
]


@pytest.mark.parametrize("lens", sorted(CAMERAS))
def test_the_rehearsal_slide_is_tracked_to_a_millimetre_with_edgelets_and_bundle_adjustment(lens):
    cfg = load_config()
    camera = CAMERAS[lens]
    n = cfg.system.warm_up_frames
    with System(camera, cfg, mode="sync") as system:
        for frame in rehearsal_frames(camera, n):
            system.process(frame)
    stamps = np.array([t for t, _ in system.trajectory])
    est = np.array([T[:3, 3] for _, T in system.trajectory])
    frame = np.round(stamps * _FPS)
    truth = np.stack([frame * _STEP_M, np.zeros_like(frame), np.zeros_like(frame)], axis=1)
    assert len(stamps) == n  # every frame tracked (measured: both lenses)
    assert ate(truth, est).rmse < 1.5e-3  # measured 0.69 mm (pinhole), 0.34 mm (fov) over a 0.59 m slide
    snap = system.mapper.snapshot
    assert snap.n_keyframes >= 4  # measured 4: initialisation's two and two more, each with new points
    assert snap.n_points >= 500  # measured 773 / 1316
    assert system.mapper.map.edgelets.n_total >= 50  # measured 94 / 97
    assert system.mapper.full_converged  # the global adjustment ran to convergence


_LIVE_START = """
import logging, sys
logging.basicConfig(level=logging.INFO, format="ptam: %(message)s", stream=sys.stderr)
import importlib
from ptam.camera.pinhole import PinholeCamera
from ptam.config import load_config
from ptam.system import System
camera = PinholeCamera(640, 480, 500.0, 500.0, 319.5, 239.5)
system = System(camera, load_config(), mode="async").start()
names = sys.argv[1:]
loaded = [n for n in names if getattr(importlib.import_module(n.rpartition(".")[0]), n.rpartition(".")[2]).signatures]
system.close()
again = System(camera, load_config(), mode="async").start()  # a second system in the process: no rehearsal
again.close()
print(len(loaded), len(names), logging.getLogger("ptam").level)
"""


def test_an_async_start_loads_the_mapper_kernels_before_the_first_frame_and_keeps_its_map_out_of_the_log():
    out = subprocess.run(
        [sys.executable, "-c", _LIVE_START, *MAPPER_KERNELS], capture_output=True, text=True, check=True
    )
    loaded, total, level = map(int, out.stdout.split())
    assert (loaded, total) == (len(MAPPER_KERNELS), len(MAPPER_KERNELS))
    assert level == 0  # the package logger's level is restored after the rehearsal
    assert not [x for x in out.stderr.splitlines() if "map initialised" in x]  # the rehearsal's map is not the user's


def test_a_rehearsal_that_waits_says_why_and_a_quick_one_prints_nothing(monkeypatch, caplog):
    log = logging.getLogger("ptam")
    with caplog.at_level(logging.INFO, logger="ptam"):
        with rehearsal_log(log):
            log.info("map initialised from frames 0 and 11: 887 points")  # the rehearsal's own line
        assert caplog.records == []
        monkeypatch.setattr(warm_up, "_NOTICE_AFTER_S", 0.0)  # as if compiling
        with rehearsal_log(log):
            for _ in range(500):
                if caplog.records:
                    break
                time.sleep(0.01)
        messages = [r.getMessage() for r in caplog.records]
        assert len(messages) == 2
        assert messages[0].startswith("loading the kernels") and messages[1].startswith("kernels ready after")
        assert log.level == logging.INFO  # restored


def test_a_failed_rehearsal_warns_in_one_line_and_the_system_still_tracks(monkeypatch, caplog):
    def broken(camera, n):
        raise ValueError("an unrenderable lens")
        yield

    monkeypatch.setattr(core, "rehearsal_frames", broken)
    monkeypatch.setattr(System, "_rehearsed", False)
    camera = CAMERAS["pinhole"]
    with caplog.at_level(logging.INFO, logger="ptam"), System(camera, load_config(), mode="async") as system:
        for frame in rehearsal_frames(camera, 20):
            system.process(frame)
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warnings == [
        "the kernel rehearsal failed (ValueError: an unrenderable lens); kernels load as the frames arrive"
    ]
    assert system.stats.frames == 20 and System._rehearsed  # tried once per process, not again on the next start
