"""New tracks on loss and track merging (Gauglitz et al. TVCG 2013 §4.4, §5.3; project issue #18)."""

from __future__ import annotations

import numpy as np
import pytest

from ptam.bench.accuracy import criteria
from ptam.eval.score import score_trajectory
from ptam.geometry import se3, so3
from ptam.geometry.sim3 import Similarity
from ptam.image.pyramid import Pyramid
from ptam.map.keyframe import KeyFrame
from ptam.map.map import SRC_TRACKER, Map
from ptam.mapping.track_merge import append_map
from ptam.system import run_dataset
from ptam.vocabulary import RunMode


def _sim(seed: int) -> Similarity:
    rng = np.random.default_rng(seed)
    return Similarity(so3.exp(rng.normal(size=3)), rng.normal(size=3), float(rng.uniform(0.3, 3.0)))


def test_a_similarity_moves_points_and_poses_together():
    """A point seen by a camera is seen at the same pixel after both are moved into the other frame; camera
    coordinates scale by s; composition applies the first similarity, then the second."""
    rng = np.random.default_rng(1)
    X = rng.normal(size=(20, 3)) + [0, 0, 5]
    T_cw = se3.exp(rng.normal(size=6) * 0.3)[None]
    sim = _sim(2)
    cam = X @ T_cw[0, :3, :3].T + T_cw[0, :3, 3]
    T2 = sim.poses_cw(T_cw)[0]
    cam2 = sim.points(X) @ T2[:3, :3].T + T2[:3, 3]
    assert np.abs(cam2 - sim.s * cam).max() < 1e-9
    assert np.abs(sim.poses_wc(se3.inv(T_cw[0])[None])[0] - se3.inv(T2)).max() < 1e-9
    other = _sim(3)
    both = sim.then(other)
    assert np.abs(both.points(X) - other.points(sim.points(X))).max() < 1e-9
    assert np.abs(sim.inverse().points(sim.points(X)) - X).max() < 1e-9


def test_appending_a_map_moves_it_and_renumbers_its_references(cfg):
    """Keyframes, points and measurements of the other map arrive after this map's, moved by the similarity,
    with keyframe and point references offset; bad points stay bad."""

    def filled(seed: int) -> Map:
        m = Map()
        rng = np.random.default_rng(seed)
        for i in range(2):
            img = rng.integers(0, 256, (96, 128)).astype(np.uint8)
            m.add_keyframe(KeyFrame(i, Pyramid.build(img, cfg.image), 2.0, 0.5), se3.exp(rng.normal(size=6) * 0.1))
        m.add_points(
            rng.normal(size=(6, 3)), np.tile([0.0, 0.0, -1.0], (6, 1)), [0, 0, 1, 1, 0, 1], 0, np.zeros((6, 2))
        )
        m.add_measurements([0, 1, 1], [0, 2, 5], rng.uniform(0, 90, (3, 2)), 0, SRC_TRACKER)
        m.mark_bad([4])
        return m

    mine, other = filled(4), filled(5)
    snap = other.snapshot()
    sim = _sim(6)
    k0, p0 = append_map(mine, snap, sim)
    assert (k0, p0) == (2, 6) and mine.n_keyframes == 4 and mine.n_points_total == 12
    assert [k.id for k in mine.keyframes] == [0, 1, 2, 3]
    assert [k.part for k in mine.keyframes] == [0, 0, 1, 1]  # they came with the first merged track
    assert np.abs(mine.X[6:] - sim.points(snap.X)).max() < 1e-12
    assert np.abs(mine.kf_T_cw[2:] - sim.poses_cw(snap.kf_T_cw)).max() < 1e-12
    assert np.array_equal(mine.source_kf[6:], snap.source_kf + 2)
    assert np.array_equal(mine.bad, np.r_[snap.bad, snap.bad])
    new = mine.meas_kf >= 2
    assert np.array_equal(mine.meas_pt[new], snap.meas_pt + 6) and np.array_equal(mine.meas_kf[new], snap.meas_kf + 2)


@pytest.mark.slow
def test_a_new_track_after_a_loss_is_merged_when_the_first_area_is_seen_again(cfg):
    """desk_tracks: covered while carried to an unmapped poster, explored there, back along the wall to the first
    poster, covered again. A new track maps the unmapped poster and merges with the first: far more frames are
    registered in the final map's frame than relocalisation alone registers, and the merged poses are right."""
    from tests.support import sequence

    d = sequence("desk_tracks")
    system = run_dataset(d, cfg, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    reloc = run_dataset(d, cfg.replace(**{"tracks.new_on_loss": False}), mode=RunMode.SYNC)
    r = score_trajectory(d / "groundtruth.txt", reloc.trajectory, criteria=criteria(cfg))
    assert system.stats.tracks_created >= 2 and system.stats.tracks_merged >= 1
    assert s.correct_fraction >= r.correct_fraction + 0.15  # measured: 0.870 against 0.552
    assert s.glitches == 0 and r.glitches == 0
    assert s.ate_rmse_m <= 2 * r.ate_rmse_m  # every merge is right (measured: 0.99 against 1.01 mm)
    assert reloc.stats.tracks_created == 1 and reloc.stats.relocalisations >= 1
    parts = [k.part for k in system.mapper.snapshot.keyframes]
    assert parts.count(0) >= 2 and parts.count(1) >= 2  # both tracks' keyframes, the merged one as part 1


@pytest.mark.slow
def test_an_unmerged_track_is_written_beside_the_trajectory(cfg, tmp_path):
    """desk_tracks cut before the walk back: the two tracks never overlap. The trajectory file holds the larger
    (the second poster, 97 frames), the first track's poses and map go beside it in their own frame, and each
    file is right in its own frame."""
    from ptam.cli import main as cli_main
    from ptam.eval.score import score_trajectory as score
    from ptam.eval.tum_io import read_tum
    from tests.support import sequence

    d = sequence("desk_tracks")
    cut = tmp_path / "cut"
    cut.mkdir()
    for name in ("camera.yaml", "groundtruth.txt"):
        (cut / name).write_bytes((d / name).read_bytes())
    (cut / "rgb").symlink_to(d / "rgb")
    (cut / "rgb.txt").write_text("".join((d / "rgb.txt").read_text().splitlines(keepends=True)[:203]))
    traj, map_ = tmp_path / "t.txt", tmp_path / "m.npz"
    argv = [
        "run",
        "--dataset",
        str(cut),
        "--no-viewer",
        "--mode",
        "sync",
        "--trajectory",
        str(traj),
        "--map",
        str(map_),
    ]
    assert cli_main(argv) == 0
    main, first = (
        score(d / "groundtruth.txt", list(zip(*read_tum(p))), criteria=criteria(cfg))
        for p in (traj, tmp_path / "t.track0.txt")
    )
    assert (tmp_path / "m.track0.npz").is_file()
    assert main.matched > first.matched >= 70  # the second poster's track is the larger
    for s in (main, first):
        assert s.glitches == 0 and s.correct == s.matched and s.ate_rmse_m < 0.002


@pytest.mark.slow
def test_twin_posters_with_different_surroundings_are_not_merged(cfg):
    """desk_twins: the second track reaches a poster identical to one the first track mapped, with other posters
    round each. The twin keyframe alone relocalises and verifies against the first map; the second track's other
    keyframes do not agree with it (measured: 0.54-0.60 of their patches are inliers against about 0.9 on their
    own map), so the tracks stay apart and nothing is reported in a wrong frame."""
    from tests.support import sequence

    d = sequence("desk_twins")
    system = run_dataset(d, cfg, mode=RunMode.SYNC)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    assert system.stats.tracks_created == 2 and system.stats.tracks_merged == 0
    assert s.glitches == 0 and s.correct == s.matched >= 140  # the larger track, in its own frame
    assert sum(map(len, system.other_tracks.values())) >= 100  # the other is kept apart, not dropped


@pytest.mark.slow
def test_a_live_user_starts_the_new_track_with_the_keys(cfg):
    """Live cameras initialise on key presses (PTAM §6.1): after the loss the same two presses start the new
    track, which merges as in auto mode."""
    from ptam.camera import load_camera
    from ptam.capture import open_dataset
    from ptam.system import System
    from tests.support import sequence

    d = sequence("desk_tracks")
    with (
        open_dataset(d, 30) as src,
        System(load_camera(d / "camera.yaml"), cfg, mode=RunMode.SYNC, init_mode="key") as system,
    ):
        for frame in src:
            if frame.index in (0, 40, 104, 140):  # first map; then, on the unmapped poster, the new track's
                system.request_keyframe()
            system.process(frame)
    s = score_trajectory(d / "groundtruth.txt", system.trajectory, criteria=criteria(cfg))
    assert system.stats.tracks_created == 2 and system.stats.tracks_merged == 1
    assert s.glitches == 0 and s.correct_fraction > 0.85  # measured: 0.870, as in auto mode
