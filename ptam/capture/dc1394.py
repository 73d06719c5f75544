"""A live FireWire IIDC camera through libdc1394 (``dc1394``, ``dc1394:N`` or ``dc1394:GUID``), as PTAM's own
Linux capture read one (PTAM §7: 640x480 at 30 Hz from a FireWire camera). IIDC cameras are not V4L2 devices
and OpenCV's wheels are built without libdc1394, so the library is bound directly (:mod:`.dc1394_lib`).

The requested size and rate go to the nearest IIDC video mode, or to a centred format-7 region whose packet
size gives the rate; MONO8, RAW8 Bayer, YUV411, YUV422 and RGB8 frames become grey for tracking (and BGR for
display). Frames come from a small DMA ring; timestamps are the driver's, in seconds. The camera is
released on every exit: ``close``, a ``with`` block, a capture error, Ctrl-C inside the iteration.
"""

from __future__ import annotations

import ctypes
import math
import select
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass

import cv2
import numpy as np

from ..config import CaptureConfig
from ..errors import InputError
from . import dc1394_lib as dc
from .frame import Frame
from .source import FrameSource

SCHEME = "dc1394"
CYCLES_PER_S = 8000  # IEEE 1394: one isochronous packet per 125 us cycle bounds a format-7 frame rate
POLL_S = 0.1  # longest wait in select() before looking again whether close() was asked from another thread

# Bits per pixel of the codings converted to grey, in order of preference: fewest bytes on the bus first.
BITS = {dc.MONO8: 8, dc.RAW8: 8, dc.YUV411: 12, dc.YUV422: 16, dc.RGB8: 24}
_RANK = {coding: i for i, coding in enumerate(BITS)}
# OpenCV's RGGB-style aliases name the sensor tile as IIDC does (COLOR_BayerRGGB2* == COLOR_BayerBG2*).
BAYER = {
    dc.FILTER_RGGB: (cv2.COLOR_BayerRGGB2GRAY, cv2.COLOR_BayerRGGB2BGR),
    dc.FILTER_GBRG: (cv2.COLOR_BayerGBRG2GRAY, cv2.COLOR_BayerGBRG2BGR),
    dc.FILTER_GRBG: (cv2.COLOR_BayerGRBG2GRAY, cv2.COLOR_BayerGRBG2BGR),
    dc.FILTER_BGGR: (cv2.COLOR_BayerBGGR2GRAY, cv2.COLOR_BayerBGGR2BGR),
}
YUV422_ORDER = {
    dc.BYTE_ORDER_UYVY: (cv2.COLOR_YUV2GRAY_UYVY, cv2.COLOR_YUV2BGR_UYVY),
    dc.BYTE_ORDER_YUYV: (cv2.COLOR_YUV2GRAY_YUY2, cv2.COLOR_YUV2BGR_YUY2),
}


def parse_camera(spec: str) -> tuple[str, int]:
    """``dc1394`` -> ("index", 0), ``dc1394:N`` (up to 3 digits) -> ("index", N), ``dc1394:GUID`` (hex, as
    printed by ``dc1394_camera_print_info``, optional 0x) -> ("guid", GUID)."""
    scheme, _, which = spec.partition(":")
    if scheme != SCHEME:
        raise InputError(f"unknown camera '{spec}' (expected dc1394, dc1394:N or dc1394:GUID)")
    if not which:
        return "index", 0
    if which.isdigit() and len(which) <= 3:
        return "index", int(which)
    try:
        return "guid", int(which.removeprefix("0x").removeprefix("0X"), 16)
    except ValueError:
        raise InputError(f"unknown IIDC camera '{which}' in '{spec}' (expected an index or a hex GUID)") from None


@dataclass(frozen=True)
class Mode:
    """One way to run the camera: a fixed IIDC mode at one of its rates, or a format-7 region and packet size."""

    video_mode: int
    coding: int
    size: tuple[int, int]
    fps: float
    framerate: int = 0  # dc1394framerate_t of a fixed mode
    packet_size: int = 0  # bytes per isochronous packet of a format-7 mode
    origin: tuple[int, int] = (0, 0)  # format-7 region's top-left corner

    @property
    def name(self) -> str:
        return dc.mode_name(self.video_mode)

    def key(self, size: tuple[int, int], fps: float) -> tuple:
        """Nearest first: size, then rate (as a ratio), then fixed modes before format 7, then bus load."""
        dsize = abs(self.size[0] - size[0]) + abs(self.size[1] - size[1])
        return (dsize, round(abs(math.log(self.fps / fps)), 6), dc.is_format7(self.video_mode), _RANK[self.coding])


def to_grey(
    rows: np.ndarray, width: int, coding: int, color_filter: int = 0, byte_order: int = dc.BYTE_ORDER_UYVY
) -> tuple[np.ndarray, np.ndarray | None]:
    """One frame's (H, stride) bytes -> (grey uint8 (H, W), BGR or None), always copies: the buffer goes back
    to the DMA ring. Grey is the luma OpenCV computes (Bayer, UYVY) or the Y samples themselves (YUV411)."""
    h = rows.shape[0]
    if coding == dc.MONO8:
        return np.array(rows[:, :width]), None
    if coding == dc.RAW8:
        if color_filter not in BAYER:
            raise InputError(f"RAW8 frames with no Bayer pattern (color filter {color_filter}) cannot be converted")
        to_gray, to_bgr = BAYER[color_filter]
        tile = rows[:, :width]
        return cv2.cvtColor(tile, to_gray), cv2.cvtColor(tile, to_bgr)
    if coding == dc.YUV422:
        to_gray, to_bgr = YUV422_ORDER.get(byte_order, YUV422_ORDER[dc.BYTE_ORDER_UYVY])
        packed = np.ascontiguousarray(rows[:, : 2 * width]).reshape(h, width, 2)
        return cv2.cvtColor(packed, to_gray), cv2.cvtColor(packed, to_bgr)
    if coding == dc.YUV411:  # U Y Y V Y Y per 4 pixels; chroma repeated into UYVY for the colour image
        packed = rows[:, : width * 3 // 2].reshape(h, width // 4, 6)
        uyvy = np.ascontiguousarray(packed[..., [0, 1, 3, 2, 0, 4, 3, 5]]).reshape(h, width, 2)
        return packed[..., [1, 2, 4, 5]].reshape(h, width), cv2.cvtColor(uyvy, cv2.COLOR_YUV2BGR_UYVY)
    if coding == dc.RGB8:
        rgb = np.ascontiguousarray(rows[:, : 3 * width]).reshape(h, width, 3)
        return cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    raise InputError(f"IIDC frames in {dc.coding_name(coding)} cannot be converted to grey")


def enumerate_cameras(lib, ctx) -> list[tuple[int, int]]:
    """(GUID, unit) of every IIDC camera libdc1394 sees; an empty list when it cannot look."""
    found = ctypes.POINTER(dc.CameraList)()
    if lib.dc1394_camera_enumerate(ctx, ctypes.pointer(found)) != dc.SUCCESS or not found:
        return []
    try:
        listing = found.contents
        return [(int(listing.ids[i].guid), int(listing.ids[i].unit)) for i in range(listing.num)]
    finally:
        lib.dc1394_camera_free_list(found)


def iidc_camera_present() -> bool:
    """Whether libdc1394 is installed and sees an IIDC camera: a hint for a failed V4L2 open, so it is cheap
    (one bus enumeration) and never raises."""
    try:
        lib = dc.load_library()
        ctx = lib.dc1394_new()
        if not ctx:
            return False
        try:
            return bool(enumerate_cameras(lib, ctx))
        finally:
            lib.dc1394_free(ctx)
    except Exception:
        return False


def _u32() -> ctypes.c_uint32:
    return ctypes.c_uint32()


def _region(want: int, most: int, step: int) -> tuple[int, int]:
    """A format-7 side: the multiple of ``step`` nearest ``want`` within ``most``, and its centred offset."""
    top = max(most // step * step, step)
    length = min(max(round(want / step) * step, step), top)
    return length, (most - length) // 2 // step * step


def _packet_size(frame_bytes: int, fps: float, unit: int, most: int) -> int:
    """Format-7 bytes per isochronous packet for ``fps``: a frame spans CYCLES_PER_S / fps cycles of one packet
    each (IIDC: the packet size sets a format-7 rate); a multiple of the camera's ``unit``, at most ``most``."""
    unit = max(unit, 1)
    largest = max(most // unit, 1) * unit
    return min(max(math.ceil(frame_bytes * fps / CYCLES_PER_S / unit), 1) * unit, largest)


class Dc1394Source(FrameSource):
    length = None

    def __init__(self, spec: str, size: tuple[int, int], fps: float, cfg: CaptureConfig, lib=None):
        """Open, configure and start the camera; ``lib`` replaces :func:`dc1394_lib.load_library` (tests)."""
        which = parse_camera(spec)
        if cfg.dc1394_dma_buffers < 1:
            raise InputError(f"capture.dc1394_dma_buffers must be at least 1, got {cfg.dc1394_dma_buffers}")
        self.name = spec
        self._lib = lib if lib is not None else dc.load_library()
        self._lock = threading.Lock()
        self._ctx = self._cam = None
        self._capturing = self._transmitting = self._closed = False
        self._fileno = -1
        self._timeout_s = cfg.dc1394_frame_timeout_s
        try:
            self._ctx = self._lib.dc1394_new()
            if not self._ctx:
                raise InputError("no IIDC camera found on the FireWire bus (libdc1394 could not start)")
            self._cam = self._open_camera(which)
            self._set_speed(cfg.dc1394_iso_speed)
            self.mode = self._choose(size, fps, cfg.dc1394_mode)
            self._start(self.mode, cfg.dc1394_dma_buffers)
        except BaseException:
            self.close()
            raise
        self.size, self.fps = self.mode.size, self.mode.fps

    def _check(self, err: int, what: str) -> None:
        if err != dc.SUCCESS:
            raise InputError(f"IIDC camera {self.name}: cannot {what}: {dc.error_text(self._lib, err)}")

    def _open_camera(self, which: tuple[str, int]):
        ids = enumerate_cameras(self._lib, self._ctx)
        if not ids:
            raise InputError("no IIDC camera found on the FireWire bus")
        seen = ", ".join(f"{guid:016x}" for guid, _ in ids)
        kind, value = which
        if kind == "index":
            if value >= len(ids):
                raise InputError(f"no IIDC camera number {value} on the FireWire bus: {len(ids)} found ({seen})")
            guid, unit = ids[value]
        else:
            units = [unit for guid, unit in ids if guid == value]
            if not units:
                raise InputError(f"no IIDC camera with GUID {value:016x} on the FireWire bus (found {seen})")
            guid, unit = value, units[0]
        cam = self._lib.dc1394_camera_new_unit(self._ctx, guid, unit)
        if not cam:
            raise InputError(f"cannot open IIDC camera {guid:016x}: check read/write permission on /dev/fw*")
        return cam

    def _set_speed(self, mbps: int) -> None:
        if mbps not in dc.ISO_SPEEDS:
            raise InputError(f"capture.dc1394_iso_speed must be one of {sorted(dc.ISO_SPEEDS)} Mb/s, got {mbps}")
        if mbps >= 800:  # S800 and up exist only in 1394b operation
            self._check(self._lib.dc1394_video_set_operation_mode(self._cam, dc.OPERATION_MODE_1394B), "use 1394b")
        self._check(self._lib.dc1394_video_set_iso_speed(self._cam, dc.ISO_SPEEDS[mbps]), f"use S{mbps}")

    def _choose(self, size: tuple[int, int], fps: float, wanted: str) -> Mode:
        """The configured mode, else the convertible mode nearest to ``size`` and ``fps``."""
        modes = dc.VideoModes()
        self._check(self._lib.dc1394_video_get_supported_modes(self._cam, ctypes.pointer(modes)), "list its modes")
        found, listed = [], []
        for m in modes.modes[: modes.num]:
            if m == dc.VIDEO_MODE_EXIF:
                continue
            mode, text = self._format7(m, size, fps) if dc.is_format7(m) else self._fixed(m, fps)
            listed.append(text)
            if mode is not None:
                found.append(mode)
        supported = f"it supports {', '.join(listed) or 'none'}"
        if wanted != "auto":
            found = [mode for mode in found if mode.name.lower() == wanted.lower()]
            if not found:
                raise InputError(f"IIDC camera {self.name} does not support mode {wanted}; {supported}")
        if not found:
            convertible = "/".join(dc.coding_name(c) for c in BITS)
            raise InputError(f"IIDC camera {self.name} has no {convertible} mode ptam can track; {supported}")
        return min(found, key=lambda mode: mode.key(size, fps))

    def _pair(self, function: str, m: int, what: str) -> tuple[int, int]:
        """Call a libdc1394 getter of two uint32 out-parameters for mode ``m``."""
        a, b = _u32(), _u32()
        self._check(getattr(self._lib, function)(self._cam, m, ctypes.pointer(a), ctypes.pointer(b)), what)
        return a.value, b.value

    def _fixed(self, m: int, fps: float) -> tuple[Mode | None, str]:
        """Fixed mode ``m`` at its rate nearest ``fps`` (None when its coding cannot be converted) and its listing."""
        name, coding, rates = dc.mode_name(m), ctypes.c_int(), dc.Framerates()
        size = self._pair("dc1394_get_image_size_from_video_mode", m, f"read the size of {name}")
        err = self._lib.dc1394_get_color_coding_from_video_mode(self._cam, m, ctypes.pointer(coding))
        self._check(err, f"read the coding of {name}")
        err = self._lib.dc1394_video_get_supported_framerates(self._cam, m, ctypes.pointer(rates))
        self._check(err, f"list the rates of {name}")
        hz = sorted(dc.FRAMERATES_HZ[r] for r in rates.framerates[: rates.num] if r in dc.FRAMERATES_HZ)
        text = f"{name} ({'/'.join(f'{r:g}' for r in hz) or 'no rate'} Hz)"
        if coding.value not in BITS or not hz:
            return None, text
        best = min(hz, key=lambda r: abs(math.log(r / fps)))
        enum = next(e for e, r in dc.FRAMERATES_HZ.items() if r == best)
        return Mode(m, coding.value, size, best, framerate=enum), text

    def _format7(self, m: int, size: tuple[int, int], fps: float) -> tuple[Mode | None, str]:
        """The centred region nearest ``size`` in format-7 mode ``m``, with the packet size that gives ``fps``."""
        name, codings = dc.mode_name(m), dc.ColorCodings()
        most = self._pair("dc1394_format7_get_max_image_size", m, f"read the size of {name}")
        step = self._pair("dc1394_format7_get_unit_size", m, f"read the size step of {name}")
        unit_bytes, max_bytes = self._pair("dc1394_format7_get_packet_parameters", m, f"read the packets of {name}")
        err = self._lib.dc1394_format7_get_color_codings(self._cam, m, ctypes.pointer(codings))
        self._check(err, f"list the codings of {name}")
        have = list(codings.codings[: codings.num])
        text = f"{name} (up to {most[0]}x{most[1]}, {'/'.join(dc.coding_name(c) for c in have)})"
        usable = sorted((c for c in have if c in BITS), key=_RANK.__getitem__)
        if not usable or not all(most):
            return None, text
        (w, left), (h, top) = (_region(size[i], most[i], max(step[i], 1)) for i in (0, 1))
        frame_bytes = w * h * BITS[usable[0]] // 8
        packet = _packet_size(frame_bytes, fps, unit_bytes, max_bytes)
        rate = CYCLES_PER_S / math.ceil(frame_bytes / packet)
        return Mode(m, usable[0], (w, h), rate, packet_size=packet, origin=(left, top)), text

    def _start(self, mode: Mode, buffers: int) -> None:
        lib, cam = self._lib, self._cam
        self._check(lib.dc1394_video_set_mode(cam, mode.video_mode), f"set mode {mode.name}")
        if dc.is_format7(mode.video_mode):
            (left, top), (w, h) = mode.origin, mode.size
            err = lib.dc1394_format7_set_roi(cam, mode.video_mode, mode.coding, mode.packet_size, left, top, w, h)
            self._check(err, f"set the {w}x{h} region of {mode.name}")
        else:
            self._check(lib.dc1394_video_set_framerate(cam, mode.framerate), f"set {mode.fps:g} Hz")
        err = lib.dc1394_capture_setup(cam, buffers, dc.CAPTURE_FLAGS_DEFAULT)
        self._check(err, f"start capture with {buffers} DMA buffers (FireWire bandwidth or channel in use?)")
        self._capturing = True
        self._check(lib.dc1394_video_set_transmission(cam, dc.ON), "start transmission")
        self._transmitting = True
        self._fileno = lib.dc1394_capture_get_fileno(cam)

    def __iter__(self) -> Iterator[Frame]:
        """Frames until closed. Stamps are the driver's capture times (microseconds, the Unix clock); a platform
        that leaves them 0 gets the host's monotonic clock on arrival instead, as the V4L2 source does."""
        index, driver_times = 0, None
        try:
            while True:
                got = self._grab()
                if got is None:
                    return
                grey, colour, stamp_us = got
                if driver_times is None:
                    driver_times = stamp_us > 0
                yield Frame(index, stamp_us / 1e6 if driver_times else time.monotonic(), grey, colour)
                index += 1
        except GeneratorExit:
            raise
        except BaseException:  # an unplugged camera, Ctrl-C while waiting: release before passing it on
            self.close()
            raise

    def _grab(self) -> tuple[np.ndarray, np.ndarray | None, int] | None:
        """The next frame's pixels and time, None once closed; waits in short slices so close() from another
        thread gets in."""
        deadline = time.monotonic() + self._timeout_s
        while True:
            with self._lock:
                if self._closed:
                    return None
                if self._fileno < 0 or select.select([self._fileno], [], [], POLL_S)[0]:
                    return self._dequeue()
            if time.monotonic() >= deadline:
                raise InputError(f"camera {self.name} stopped delivering frames (none for {self._timeout_s:g} s)")

    def _dequeue(self) -> tuple[np.ndarray, np.ndarray | None, int]:
        """(grey, colour, driver time in microseconds) of the oldest frame in the ring, its buffer given back."""
        lib, cam = self._lib, self._cam
        held = ctypes.POINTER(dc.VideoFrame)()
        err = lib.dc1394_capture_dequeue(cam, dc.CAPTURE_POLICY_WAIT, ctypes.pointer(held))
        if err != dc.SUCCESS or not held:
            why = dc.error_text(lib, err) if err != dc.SUCCESS else "no frame"
            raise InputError(f"camera {self.name} stopped delivering frames ({why})")
        try:
            f = held.contents
            w, h = int(f.size[0]), int(f.size[1])
            stride = int(f.stride) or w * BITS.get(f.color_coding, 8) // 8
            if not f.image or stride * h > max(int(f.total_bytes), int(f.image_bytes)):
                raise InputError(f"camera {self.name} delivered a short frame ({f.image_bytes} bytes for {w}x{h})")
            rows = np.ctypeslib.as_array(f.image, shape=(h, stride))
            return (*to_grey(rows, w, f.color_coding, f.color_filter, f.yuv_byte_order), int(f.timestamp))
        finally:
            lib.dc1394_capture_enqueue(cam, held)

    def close(self) -> None:
        """Stop transmission, stop capture, free the camera and the library context; once, whatever was reached."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            lib, cam = self._lib, self._cam
            try:
                if self._transmitting:
                    lib.dc1394_video_set_transmission(cam, dc.OFF)
                if self._capturing:
                    lib.dc1394_capture_stop(cam)
            finally:
                if cam:
                    lib.dc1394_camera_free(cam)
                if self._ctx:
                    lib.dc1394_free(self._ctx)
                self._cam = self._ctx = None
