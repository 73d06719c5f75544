"""The FireWire IIDC (libdc1394) camera source, without a camera: a Python stand-in for libdc1394 that speaks the
same ctypes calls (out-parameters filled through the pointers, frames as real ``dc1394video_frame_t`` structs)
delivers synthetic frames and records every call; one test runs ``ptam`` against the real library and an
empty bus."""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import subprocess
import sys
import threading

import cv2
import numpy as np
import pytest

from ptam.capture import Dc1394Source, open_source
from ptam.capture import dc1394_lib as dc
from ptam.capture import v4l2 as v4l2_module
from ptam.capture.dc1394 import iidc_camera_present, parse_camera, to_grey
from ptam.errors import InputError
from tests.support import capture, config

GUID, OTHER_GUID = 0x00B09D0100A1B2C3, 0x00B09D0100D4E5F6
MODE = {name: dc.VIDEO_MODE_MIN + i for i, name in enumerate(dc.VIDEO_MODE_NAMES)}
RATE = {hz: enum for enum, hz in dc.FRAMERATES_HZ.items()}
BITS = {dc.MONO8: 8, dc.RAW8: 8, dc.YUV411: 12, dc.YUV422: 16, dc.RGB8: 24, dc.MONO16: 16, dc.YUV444: 24}
RELEASE = ["dc1394_video_set_transmission", "dc1394_capture_stop", "dc1394_camera_free", "dc1394_free"]


def fixed(name: str, coding: int, *rates: float) -> dict:
    w, h = (int(v) for v in name.split("_")[0].split("x"))
    return {"mode": MODE[name], "size": (w, h), "coding": coding, "rates": [RATE[r] for r in rates]}


def format7(i: int, most: tuple[int, int], codings: list[int], unit=(8, 2), packets=(4, 4096)) -> dict:
    return {"mode": MODE[f"FORMAT7_{i}"], "max": most, "unit": unit, "codings": codings, "packets": packets}


class FakeLib:
    """libdc1394 as the source calls it. ``frames`` are the byte images delivered in turn (then the last one
    again); ``fail_at`` / ``interrupt_at`` make that dequeue fail / raise KeyboardInterrupt."""

    def __init__(self, cameras=((GUID, 0),), modes=None, frames=None, coding=dc.MONO8, **frame_fields):
        self.cameras, self.modes = list(cameras), modes or [fixed("640x480_MONO8", dc.MONO8, 15.0, 30.0)]
        self.frames, self.coding, self.frame_fields = frames, coding, frame_fields
        self.calls: list[tuple] = []
        self.fail_at = self.interrupt_at = None
        self.fileno, self.mode, self.roi, self.delivered, self.enqueued = -1, None, None, 0, 0
        self._keep = []  # ctypes objects the "library" owns while the source reads them

    def __getattr__(self, name):
        if not name.startswith("dc1394_"):
            raise AttributeError(name)
        impl = getattr(self, "_" + name[len("dc1394_") :], None)

        def call(*args):
            self.calls.append((name, *args))
            return impl(*args) if impl else dc.SUCCESS

        return call

    def names(self) -> list[str]:
        return [c[0] for c in self.calls]

    def _find(self, m):
        return next(d for d in self.modes if d["mode"] == m)

    def _new(self):
        return "ctx"

    def _camera_enumerate(self, ctx, out):
        ids = (dc.CameraId * max(len(self.cameras), 1))(*(dc.CameraId(unit, guid) for guid, unit in self.cameras))
        listing = dc.CameraList(len(self.cameras), ids)
        self._keep += [ids, listing]
        out[0] = ctypes.pointer(listing)
        return dc.SUCCESS

    def _camera_new_unit(self, ctx, guid, unit):
        return "cam"

    def _video_get_supported_modes(self, cam, out):
        out.contents.num = len(self.modes)
        for i, d in enumerate(self.modes):
            out.contents.modes[i] = d["mode"]
        return dc.SUCCESS

    def _video_get_supported_framerates(self, cam, m, out):
        rates = self._find(m)["rates"]
        out.contents.num = len(rates)
        for i, r in enumerate(rates):
            out.contents.framerates[i] = r
        return dc.SUCCESS

    def _get_image_size_from_video_mode(self, cam, m, w, h):
        w[0], h[0] = self._find(m)["size"]
        return dc.SUCCESS

    def _get_color_coding_from_video_mode(self, cam, m, out):
        out[0] = self._find(m)["coding"]
        return dc.SUCCESS

    def _format7_get_max_image_size(self, cam, m, w, h):
        w[0], h[0] = self._find(m)["max"]
        return dc.SUCCESS

    def _format7_get_unit_size(self, cam, m, w, h):
        w[0], h[0] = self._find(m)["unit"]
        return dc.SUCCESS

    def _format7_get_packet_parameters(self, cam, m, unit, most):
        unit[0], most[0] = self._find(m)["packets"]
        return dc.SUCCESS

    def _format7_get_color_codings(self, cam, m, out):
        codings = self._find(m)["codings"]
        out.contents.num = len(codings)
        for i, c in enumerate(codings):
            out.contents.codings[i] = c
        return dc.SUCCESS

    def _video_set_mode(self, cam, m):
        self.mode = m
        return dc.SUCCESS

    def _format7_set_roi(self, cam, m, coding, packet, left, top, w, h):
        self.roi = (coding, packet, left, top, w, h)
        return dc.SUCCESS

    def _capture_get_fileno(self, cam):
        return self.fileno

    def _size(self):
        d = self._find(self.mode)
        return (self.roi[4], self.roi[5]) if "max" in d else d["size"]

    def _capture_dequeue(self, cam, policy, out):
        n = self.delivered
        if n == self.interrupt_at:
            raise KeyboardInterrupt
        if n == self.fail_at:
            return -1
        w, h = self._size()
        coding = self.roi[0] if self.roi else self.coding
        data = self.frames[min(n, len(self.frames) - 1)] if self.frames else np.full((h, w), n, np.uint8)
        data = np.ascontiguousarray(data).reshape(h, -1)
        buf = (ctypes.c_ubyte * data.size).from_buffer_copy(data.tobytes())
        frame = dc.VideoFrame(image=ctypes.cast(buf, ctypes.POINTER(ctypes.c_ubyte)), color_coding=coding)
        frame.size[0], frame.size[1] = w, h
        frame.stride, frame.image_bytes, frame.total_bytes = data.shape[1], w * h * BITS[coding] // 8, data.size
        frame.timestamp = 1_700_000_000_000_000 + n * 33_333
        frame.yuv_byte_order = dc.BYTE_ORDER_UYVY
        for key, value in self.frame_fields.items():
            setattr(frame, key, value)
        self._keep += [buf, frame]
        self.delivered += 1
        out[0] = ctypes.pointer(frame)
        return dc.SUCCESS

    def _capture_enqueue(self, cam, frame):
        self.enqueued += 1
        return dc.SUCCESS

    def _error_get_string(self, code):
        return b"DC1394_FAILURE"


def source(lib: FakeLib, spec="dc1394", size=(640, 480), fps=30.0, **changes) -> Dc1394Source:
    cfg = config().replace(**{f"capture.{k}": v for k, v in changes.items()}) if changes else config()
    return Dc1394Source(spec, size, fps, cfg.capture, lib=lib)


def take(src, n: int) -> list:
    frames = []
    for frame in src:
        frames.append(frame)
        if len(frames) == n:
            break
    return frames


def test_parse_camera():
    assert parse_camera("dc1394") == ("index", 0)
    assert parse_camera("dc1394:1") == ("index", 1)
    assert parse_camera("dc1394:00b09d0100a1b2c3") == ("guid", GUID)
    assert parse_camera("dc1394:0x00B09D0100A1B2C3") == ("guid", GUID)
    with pytest.raises(InputError, match="expected an index or a hex GUID"):
        parse_camera("dc1394:front")


def test_missing_library_names_the_debian_package(monkeypatch):
    monkeypatch.setattr(dc, "SONAME", "libdc1394-not-here.so.0")
    monkeypatch.setattr(ctypes.util, "find_library", lambda name: None)
    expected = r"^--camera dc1394 needs libdc1394, which is not installed: apt-get install libdc1394-25$"
    with pytest.raises(InputError, match=expected):
        open_source(capture(), camera="dc1394")


def test_open_source_dispatches_and_mono8_passes_through(monkeypatch):
    lib = FakeLib()
    monkeypatch.setattr(dc, "load_library", lambda soname=None: lib)
    with open_source(capture(), camera="dc1394:0", size="640x480", fps=30.0) as src:
        assert isinstance(src, Dc1394Source) and src.size == (640, 480) and src.fps == 30.0 and src.length is None
        frames = take(src, 3)
    assert [f.index for f in frames] == [0, 1, 2]
    assert [int(f.image[0, 0]) for f in frames] == [0, 1, 2] and all(f.colour is None for f in frames)
    assert frames[0].image.shape == (480, 640) and frames[0].image.dtype == np.uint8 and frames[0].image.flags.writeable
    stamps = [f.timestamp for f in frames]
    assert stamps == sorted(set(stamps))
    np.testing.assert_allclose(stamps, [1_700_000_000.0, 1_700_000_000.033333, 1_700_000_000.066666])
    assert lib.enqueued == lib.delivered == 3  # every DMA buffer goes back to the ring
    setup = next(c for c in lib.calls if c[0] == "dc1394_capture_setup")
    assert setup == ("dc1394_capture_setup", "cam", 4, dc.CAPTURE_FLAGS_DEFAULT)
    assert ("dc1394_video_set_iso_speed", "cam", dc.ISO_SPEEDS[400]) in lib.calls
    assert ("dc1394_video_set_framerate", "cam", RATE[30.0]) in lib.calls
    assert lib.names()[-4:] == RELEASE and lib.calls[-4] == ("dc1394_video_set_transmission", "cam", dc.OFF)


def test_host_clock_when_the_driver_gives_no_time():
    with source(FakeLib(timestamp=0)) as src:
        stamps = [f.timestamp for f in take(src, 3)]
    assert stamps == sorted(set(stamps)) and stamps[0] < 1e9  # monotonic seconds, not the Unix clock


def test_mono8_rows_with_padding():
    rows = np.arange(480 * 648, dtype=np.uint32).astype(np.uint8).reshape(480, 648)
    with source(FakeLib(frames=[rows])) as src:
        (frame,) = take(src, 1)
    np.testing.assert_array_equal(frame.image, rows[:, :640])


BAYER_OPENCV = {  # OpenCV names a Bayer code by the second row's 2nd and 3rd pixels (its docs)
    dc.FILTER_RGGB: (cv2.COLOR_BayerBG2GRAY, cv2.COLOR_BayerBG2BGR, (0, 0)),
    dc.FILTER_GBRG: (cv2.COLOR_BayerGR2GRAY, cv2.COLOR_BayerGR2BGR, (1, 0)),
    dc.FILTER_GRBG: (cv2.COLOR_BayerGB2GRAY, cv2.COLOR_BayerGB2BGR, (0, 1)),
    dc.FILTER_BGGR: (cv2.COLOR_BayerRG2GRAY, cv2.COLOR_BayerRG2BGR, (1, 1)),
}


@pytest.mark.parametrize("pattern", list(BAYER_OPENCV), ids=["RGGB", "GBRG", "GRBG", "BGGR"])
def test_bayer_to_grey_is_opencvs(pattern):
    to_gray, to_bgr, red_at = BAYER_OPENCV[pattern]
    raw = np.random.default_rng(pattern).integers(0, 256, (240, 320), dtype=np.uint8)
    lib = FakeLib(modes=[format7(0, (320, 240), [dc.RAW8])], frames=[raw], color_filter=pattern)
    with source(lib, size=(320, 240)) as src:
        (frame,) = take(src, 1)
    np.testing.assert_array_equal(frame.image, cv2.cvtColor(raw, to_gray))
    np.testing.assert_array_equal(frame.colour, cv2.cvtColor(raw, to_bgr))
    # The tile means what IIDC says: a red scene mosaicked with red where the pattern puts it stays red.
    mosaic = np.full((16, 16), 20, np.uint8)
    mosaic[red_at[0] :: 2, red_at[1] :: 2] = 220
    _, colour = to_grey(mosaic, 16, dc.RAW8, pattern)
    b, g, r = colour[4:-4, 4:-4].reshape(-1, 3).mean(axis=0)
    assert r > 200 and g < 40 and b < 40


def test_yuv422_uyvy_to_grey_is_opencvs():
    uyvy = np.random.default_rng(1).integers(0, 256, (240, 640), dtype=np.uint8)
    lib = FakeLib(modes=[fixed("320x240_YUV422", dc.YUV422, 30.0)], frames=[uyvy], coding=dc.YUV422)
    with source(lib, size=(320, 240)) as src:
        (frame,) = take(src, 1)
    packed = uyvy.reshape(240, 320, 2)
    np.testing.assert_array_equal(frame.image, cv2.cvtColor(packed, cv2.COLOR_YUV2GRAY_UYVY))
    np.testing.assert_array_equal(frame.image, uyvy[:, 1::2])  # UYVY: luma is every second byte
    np.testing.assert_array_equal(frame.colour, cv2.cvtColor(packed, cv2.COLOR_YUV2BGR_UYVY))


def test_yuv411_and_rgb8_to_grey():
    yuv411 = np.random.default_rng(2).integers(0, 256, (480, 960), dtype=np.uint8)
    grey, colour = to_grey(yuv411, 640, dc.YUV411)
    np.testing.assert_array_equal(grey, yuv411.reshape(480, 160, 6)[..., [1, 2, 4, 5]].reshape(480, 640))
    assert colour.shape == (480, 640, 3)
    rgb = np.random.default_rng(3).integers(0, 256, (4, 6, 3), dtype=np.uint8)
    grey, colour = to_grey(rgb.reshape(4, 18), 6, dc.RGB8)
    np.testing.assert_array_equal(grey, cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY))
    np.testing.assert_array_equal(colour, rgb[..., ::-1])


CAMERA_MODES = [
    fixed("320x240_YUV422", dc.YUV422, 15.0, 30.0),
    fixed("640x480_YUV411", dc.YUV411, 15.0, 30.0),
    fixed("640x480_MONO8", dc.MONO8, 7.5, 15.0),
    fixed("1024x768_MONO8", dc.MONO8, 7.5, 15.0),
]


@pytest.mark.parametrize(
    "size, fps, mode, granted_fps",
    [
        ((640, 480), 30.0, "640x480_YUV411", 30.0),  # the only 640x480 mode at 30 Hz
        ((640, 480), 15.0, "640x480_MONO8", 15.0),  # both at 15 Hz: fewer bytes on the bus
        ((640, 480), 60.0, "640x480_YUV411", 30.0),  # size first, then the nearest rate
        ((1000, 700), 30.0, "1024x768_MONO8", 15.0),
        ((300, 200), 20.0, "320x240_YUV422", 15.0),
    ],
)
def test_nearest_mode(size, fps, mode, granted_fps):
    lib = FakeLib(modes=CAMERA_MODES)
    with source(lib, size=size, fps=fps) as src:
        assert lib.mode == MODE[mode] and src.fps == granted_fps
        assert src.size == next(d["size"] for d in CAMERA_MODES if d["mode"] == MODE[mode])
        assert ("dc1394_video_set_framerate", "cam", RATE[granted_fps]) in lib.calls


def test_format7_region_and_packet_size():
    lib = FakeLib(modes=[format7(0, (1280, 960), [dc.YUV422, dc.RAW8, dc.MONO16])])
    with source(lib, size=(640, 480), fps=30.0) as src:
        # Centred 640x480 region in RAW8 (fewer bytes than YUV422). 307200 bytes in 8000/30 = 266.7 cycles:
        # packets of 1152 bytes (a multiple of the 4-byte unit), 267 of them a frame, so 8000/267 Hz.
        assert lib.roi == (dc.RAW8, 1152, 320, 240, 640, 480)
        assert src.size == (640, 480) and src.fps == pytest.approx(8000 / 267)
    lib = FakeLib(modes=[format7(1, (1280, 960), [dc.MONO8], unit=(16, 16), packets=(8, 1000))])
    with source(lib, size=(2000, 500), fps=60.0) as src:
        assert lib.roi == (dc.MONO8, 1000, 0, 224, 1280, 496)  # width clipped, height and offset in 16-pixel steps
        assert src.fps == pytest.approx(8000 / 635)  # packets capped at 1000 bytes: slower than asked


def test_fixed_mode_preferred_to_format7_at_equal_fit():
    lib = FakeLib(modes=[format7(0, (640, 480), [dc.MONO8]), fixed("640x480_MONO8", dc.MONO8, 30.0)])
    with source(lib) as src:
        assert lib.mode == MODE["640x480_MONO8"] and lib.roi is None and src.fps == 30.0


def test_configured_mode_and_unsupported_mode():
    lib = FakeLib(modes=CAMERA_MODES)
    with source(lib, dc1394_mode="640x480_mono8") as src:
        assert lib.mode == MODE["640x480_MONO8"] and src.fps == 15.0
    lib = FakeLib(modes=CAMERA_MODES[:3])
    expected = (
        r"^IIDC camera dc1394 does not support mode 800x600_MONO8; it supports 320x240_YUV422 \(15/30 Hz\), "
        r"640x480_YUV411 \(15/30 Hz\), 640x480_MONO8 \(7.5/15 Hz\)$"
    )
    with pytest.raises(InputError, match=expected):
        source(lib, dc1394_mode="800x600_MONO8")
    assert lib.names()[-2:] == ["dc1394_camera_free", "dc1394_free"]


def test_camera_with_no_convertible_mode():
    lib = FakeLib(modes=[fixed("640x480_MONO16", dc.MONO16, 30.0), format7(0, (1280, 960), [dc.YUV444])])
    expected = (
        r"^IIDC camera dc1394 has no MONO8/RAW8/YUV411/YUV422/RGB8 mode ptam can track; it supports "
        r"640x480_MONO16 \(30 Hz\), FORMAT7_0 \(up to 1280x960, YUV444\)$"
    )
    with pytest.raises(InputError, match=expected):
        source(lib)


def test_camera_chosen_by_guid_or_index():
    lib = FakeLib(cameras=[(GUID, 0), (OTHER_GUID, 1)])
    source(lib, spec=f"dc1394:{OTHER_GUID:016x}").close()
    assert ("dc1394_camera_new_unit", "ctx", OTHER_GUID, 1) in lib.calls
    lib = FakeLib(cameras=[(GUID, 0), (OTHER_GUID, 1)])
    source(lib, spec="dc1394:1").close()
    assert ("dc1394_camera_new_unit", "ctx", OTHER_GUID, 1) in lib.calls


def test_guid_or_index_not_found():
    lib = FakeLib()
    expected = r"^no IIDC camera with GUID 00b09d0100ffffff on the FireWire bus \(found 00b09d0100a1b2c3\)$"
    with pytest.raises(InputError, match=expected):
        source(lib, spec="dc1394:00b09d0100ffffff")
    assert lib.names()[-1] == "dc1394_free" and "dc1394_camera_new_unit" not in lib.names()
    with pytest.raises(
        InputError, match=r"^no IIDC camera number 2 on the FireWire bus: 1 found \(00b09d0100a1b2c3\)$"
    ):
        source(FakeLib(), spec="dc1394:2")


def test_no_camera_on_the_bus():
    lib = FakeLib(cameras=[])
    with pytest.raises(InputError, match=r"^no IIDC camera found on the FireWire bus$"):
        source(lib)
    assert lib.names()[-2:] == ["dc1394_camera_free_list", "dc1394_free"]


def test_released_once_on_close_and_with_block():
    lib = FakeLib()
    src = source(lib)
    src.close()
    src.close()
    assert lib.names()[-4:] == RELEASE and lib.names().count("dc1394_free") == 1
    assert list(src) == []  # a closed source delivers nothing
    lib = FakeLib()
    with pytest.raises(KeyboardInterrupt), source(lib) as src:  # Ctrl-C in the consumer: the with block releases
        for _ in src:
            raise KeyboardInterrupt
    assert lib.names()[-4:] == RELEASE


def test_capture_error_mid_run_releases_and_reports():
    lib = FakeLib()
    lib.fail_at = 2
    src = source(lib)
    got = []
    with pytest.raises(InputError, match=r"^camera dc1394 stopped delivering frames \(DC1394_FAILURE \(-1\)\)$"):
        for frame in src:
            got.append(frame)
    assert len(got) == 2 and lib.names()[-4:] == RELEASE
    src.close()
    assert lib.names().count("dc1394_free") == 1


def test_ctrl_c_while_waiting_for_a_frame_releases():
    lib = FakeLib()
    lib.interrupt_at = 1
    src = source(lib)
    with pytest.raises(KeyboardInterrupt):
        for _ in src:
            pass
    assert lib.names()[-4:] == RELEASE


def test_silent_camera_times_out_and_close_from_another_thread():
    read_end, write_end = os.pipe()
    try:
        lib = FakeLib()
        lib.fileno = read_end  # never readable: no frame ever arrives
        src = source(lib, dc1394_frame_timeout_s=0.3)
        with pytest.raises(InputError, match=r"^camera dc1394 stopped delivering frames \(none for 0.3 s\)$"):
            next(iter(src))
        assert lib.names()[-4:] == RELEASE
        lib = FakeLib()
        lib.fileno = read_end
        src = source(lib, dc1394_frame_timeout_s=60.0)
        got = []
        reader = threading.Thread(target=lambda: got.extend(src))
        reader.start()
        src.close()  # as `ptam run` does after its realtime reader: the wait ends, the camera is released
        reader.join(5.0)
        assert not reader.is_alive() and got == [] and lib.names()[-4:] == RELEASE
        os.write(write_end, b"x")  # readable: frames are dequeued
        lib = FakeLib()
        lib.fileno = read_end
        with source(lib) as src:
            assert len(take(src, 2)) == 2
    finally:
        os.close(read_end)
        os.close(write_end)


def test_iso_speed_and_ring_from_config():
    lib = FakeLib()
    source(lib, dc1394_iso_speed=800, dc1394_dma_buffers=2).close()
    names = lib.names()
    assert names.index("dc1394_video_set_operation_mode") < names.index("dc1394_video_set_iso_speed")
    assert ("dc1394_video_set_iso_speed", "cam", dc.ISO_SPEEDS[800]) in lib.calls
    assert ("dc1394_capture_setup", "cam", 2, dc.CAPTURE_FLAGS_DEFAULT) in lib.calls
    with pytest.raises(InputError, match=r"^capture.dc1394_iso_speed must be one of .* Mb/s, got 500$"):
        source(FakeLib(), dc1394_iso_speed=500)


class ClosedCapture:
    def __init__(self, device, api):
        pass

    def isOpened(self):
        return False

    def release(self):
        pass


def test_v4l2_failure_points_at_an_iidc_camera(monkeypatch):
    monkeypatch.setattr(v4l2_module.cv2, "VideoCapture", ClosedCapture)
    monkeypatch.setattr(dc, "load_library", lambda soname=None: FakeLib())
    assert iidc_camera_present()
    expected = (
        r"^cannot open camera v4l2: no V4L2 device, but an IIDC \(FireWire\) camera is on the bus: "
        r"use --camera dc1394$"
    )
    with pytest.raises(InputError, match=expected):
        open_source(capture(), camera="v4l2")
    monkeypatch.setattr(dc, "load_library", lambda soname=None: FakeLib(cameras=[]))
    with pytest.raises(InputError, match=r"^cannot open camera v4l2$"):
        open_source(capture(), camera="v4l2")

    def missing(soname=None):
        raise dc.missing_library_error()

    monkeypatch.setattr(dc, "load_library", missing)
    assert not iidc_camera_present()
    with pytest.raises(InputError, match=r"^cannot open camera v4l2$"):
        open_source(capture(), camera="v4l2")


_REAL_LIBRARY = ctypes.util.find_library("dc1394") is not None or bool(os.environ.get("CI"))  # CI installs it


def test_real_library_loads_with_its_prototypes():
    """With libdc1394 installed the prototypes bind; without it, the same call gives the one-line error."""
    if not _REAL_LIBRARY:
        with pytest.raises(InputError, match="apt-get install libdc1394-25"):
            dc.load_library()
        return
    lib = dc.load_library()
    assert lib.dc1394_capture_dequeue.argtypes[2] is ctypes.POINTER(ctypes.POINTER(dc.VideoFrame))
    assert ctypes.sizeof(dc.VideoFrame) == 120  # x86-64 / aarch64 layout of dc1394video_frame_t (video.h)


@pytest.mark.parametrize("command", [["run", "--no-viewer"], ["calibrate"]])
def test_cli_with_no_iidc_camera_on_the_bus(command, tmp_path):
    """No camera here (nor in CI): with the library, "no IIDC camera"; without it, the package to install."""
    expected = "no IIDC camera" if _REAL_LIBRARY else "apt-get install libdc1394-25"
    env = {**os.environ, "HOME": str(tmp_path), "XDG_CACHE_HOME": str(tmp_path / "cache")}
    proc = subprocess.run(
        [sys.executable, "-m", "ptam", command[0], "--camera", "dc1394", *command[1:]],
        cwd=tmp_path,
        env=env,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and expected in lines[0], proc.stderr
