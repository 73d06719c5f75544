"""A ctypes binding of the part of libdc1394 v2 that capture needs (PTAM §7: PTAM's own Linux capture read
FireWire IIDC cameras through libdc1394). ctypes, not a compiled extension: nothing is built at install time
and no pip package is added; the library is the distribution's (Debian ``libdc1394-25``).

Enum values and struct layouts are those of ``/usr/include/dc1394/*.h`` (libdc1394 2.2). Handles
(``dc1394_t *``, ``dc1394camera_t *``) stay opaque ``void *``; out-parameters are passed as
``ctypes.pointer(...)`` so a pure-Python stand-in for the library (tests) can fill them with ``p[0] = ...``.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import logging

from ..errors import InputError

SONAME = "libdc1394.so.25"
DEBIAN_PACKAGE = "libdc1394-25"

# dc1394error_t
SUCCESS = 0

# dc1394video_mode_t: consecutive from 64 (types.h); names without the DC1394_VIDEO_MODE_ prefix.
VIDEO_MODE_MIN = 64
VIDEO_MODE_NAMES = (
    "160x120_YUV444",
    "320x240_YUV422",
    "640x480_YUV411",
    "640x480_YUV422",
    "640x480_RGB8",
    "640x480_MONO8",
    "640x480_MONO16",
    "800x600_YUV422",
    "800x600_RGB8",
    "800x600_MONO8",
    "1024x768_YUV422",
    "1024x768_RGB8",
    "1024x768_MONO8",
    "800x600_MONO16",
    "1024x768_MONO16",
    "1280x960_YUV422",
    "1280x960_RGB8",
    "1280x960_MONO8",
    "1600x1200_YUV422",
    "1600x1200_RGB8",
    "1600x1200_MONO8",
    "1280x960_MONO16",
    "1600x1200_MONO16",
    "EXIF",
    *(f"FORMAT7_{i}" for i in range(8)),
)
VIDEO_MODE_NUM = len(VIDEO_MODE_NAMES)  # 32
VIDEO_MODE_EXIF = VIDEO_MODE_MIN + VIDEO_MODE_NAMES.index("EXIF")
VIDEO_MODE_FORMAT7_0 = VIDEO_MODE_MIN + VIDEO_MODE_NAMES.index("FORMAT7_0")

# dc1394color_coding_t: consecutive from 352.
COLOR_CODING_NAMES = (
    "MONO8",
    "YUV411",
    "YUV422",
    "YUV444",
    "RGB8",
    "MONO16",
    "RGB16",
    "MONO16S",
    "RGB16S",
    "RAW8",
    "RAW16",
)
COLOR_CODING_MIN = 352
COLOR_CODING_NUM = len(COLOR_CODING_NAMES)  # 11
MONO8, YUV411, YUV422, YUV444, RGB8, MONO16, RGB16, MONO16S, RGB16S, RAW8, RAW16 = range(
    COLOR_CODING_MIN, COLOR_CODING_MIN + COLOR_CODING_NUM
)

# dc1394color_filter_t (Bayer tile of RAW modes) and dc1394byte_order_t (422 modes).
FILTER_RGGB, FILTER_GBRG, FILTER_GRBG, FILTER_BGGR = range(512, 516)
BYTE_ORDER_UYVY, BYTE_ORDER_YUYV = 800, 801

# dc1394framerate_t: consecutive from 32, each twice the previous, 1.875 to 240 Hz.
FRAMERATE_MIN = 32
FRAMERATE_NUM = 8
FRAMERATES_HZ = {FRAMERATE_MIN + i: 1.875 * 2**i for i in range(FRAMERATE_NUM)}

# dc1394speed_t (Mb/s -> enum) and dc1394operation_mode_t: S800 and up need 1394b operation.
ISO_SPEEDS = {100: 0, 200: 1, 400: 2, 800: 3, 1600: 4, 3200: 5}
OPERATION_MODE_LEGACY, OPERATION_MODE_1394B = 480, 481

CAPTURE_POLICY_WAIT = 672
CAPTURE_FLAGS_DEFAULT = 0x00000004
OFF, ON = 0, 1
LOG_ERROR, LOG_WARNING, LOG_DEBUG = 768, 769, 770
USE_RECOMMENDED = -3  # format7.h: packet size chosen by the camera


class CameraId(ctypes.Structure):
    _fields_ = [("unit", ctypes.c_uint16), ("guid", ctypes.c_uint64)]


class CameraList(ctypes.Structure):
    _fields_ = [("num", ctypes.c_uint32), ("ids", ctypes.POINTER(CameraId))]


class VideoModes(ctypes.Structure):
    _fields_ = [("num", ctypes.c_uint32), ("modes", ctypes.c_int * VIDEO_MODE_NUM)]


class Framerates(ctypes.Structure):
    _fields_ = [("num", ctypes.c_uint32), ("framerates", ctypes.c_int * FRAMERATE_NUM)]


class ColorCodings(ctypes.Structure):
    _fields_ = [("num", ctypes.c_uint32), ("codings", ctypes.c_int * COLOR_CODING_NUM)]


class VideoFrame(ctypes.Structure):
    """dc1394video_frame_t (video.h)."""

    _fields_ = [
        ("image", ctypes.POINTER(ctypes.c_ubyte)),
        ("size", ctypes.c_uint32 * 2),
        ("position", ctypes.c_uint32 * 2),
        ("color_coding", ctypes.c_int),
        ("color_filter", ctypes.c_int),
        ("yuv_byte_order", ctypes.c_uint32),
        ("data_depth", ctypes.c_uint32),
        ("stride", ctypes.c_uint32),
        ("video_mode", ctypes.c_int),
        ("total_bytes", ctypes.c_uint64),
        ("image_bytes", ctypes.c_uint32),
        ("padding_bytes", ctypes.c_uint32),
        ("packet_size", ctypes.c_uint32),
        ("packets_per_frame", ctypes.c_uint32),
        ("timestamp", ctypes.c_uint64),
        ("frames_behind", ctypes.c_uint32),
        ("camera", ctypes.c_void_p),
        ("id", ctypes.c_uint32),
        ("allocated_image_bytes", ctypes.c_uint64),
        ("little_endian", ctypes.c_int),
        ("data_in_padding", ctypes.c_int),
    ]


_P = ctypes.POINTER
_VOID, _INT, _U32, _U64 = ctypes.c_void_p, ctypes.c_int, ctypes.c_uint32, ctypes.c_uint64
_PU32 = _P(_U32)

# name: (restype, argtypes). Every dc1394error_t is an int (0 = success, negative = error).
PROTOTYPES = {
    "dc1394_new": (_VOID, []),
    "dc1394_free": (None, [_VOID]),
    "dc1394_camera_enumerate": (_INT, [_VOID, _P(_P(CameraList))]),
    "dc1394_camera_free_list": (None, [_P(CameraList)]),
    "dc1394_camera_new": (_VOID, [_VOID, _U64]),
    "dc1394_camera_new_unit": (_VOID, [_VOID, _U64, _INT]),
    "dc1394_camera_free": (None, [_VOID]),
    "dc1394_video_get_supported_modes": (_INT, [_VOID, _P(VideoModes)]),
    "dc1394_video_get_supported_framerates": (_INT, [_VOID, _INT, _P(Framerates)]),
    "dc1394_get_image_size_from_video_mode": (_INT, [_VOID, _INT, _PU32, _PU32]),
    "dc1394_get_color_coding_from_video_mode": (_INT, [_VOID, _INT, _P(_INT)]),
    "dc1394_video_set_operation_mode": (_INT, [_VOID, _INT]),
    "dc1394_video_set_iso_speed": (_INT, [_VOID, _INT]),
    "dc1394_video_set_mode": (_INT, [_VOID, _INT]),
    "dc1394_video_set_framerate": (_INT, [_VOID, _INT]),
    "dc1394_video_set_transmission": (_INT, [_VOID, _INT]),
    "dc1394_format7_get_max_image_size": (_INT, [_VOID, _INT, _PU32, _PU32]),
    "dc1394_format7_get_unit_size": (_INT, [_VOID, _INT, _PU32, _PU32]),
    "dc1394_format7_get_color_codings": (_INT, [_VOID, _INT, _P(ColorCodings)]),
    "dc1394_format7_get_packet_parameters": (_INT, [_VOID, _INT, _PU32, _PU32]),
    "dc1394_format7_set_roi": (_INT, [_VOID, _INT, _INT, ctypes.c_int32] + [ctypes.c_int32] * 4),
    "dc1394_capture_setup": (_INT, [_VOID, _U32, _U32]),
    "dc1394_capture_get_fileno": (_INT, [_VOID]),
    "dc1394_capture_dequeue": (_INT, [_VOID, _INT, _P(_P(VideoFrame))]),
    "dc1394_capture_enqueue": (_INT, [_VOID, _P(VideoFrame)]),
    "dc1394_capture_stop": (_INT, [_VOID]),
    "dc1394_error_get_string": (ctypes.c_char_p, [_INT]),
    "dc1394_log_register_handler": (_INT, [_INT, _VOID, _VOID]),
}

log = logging.getLogger("ptam")

# libdc1394 prints its own errors on stderr; ours are one line, so its messages go to the debug log instead.
_LOG_HANDLER = ctypes.CFUNCTYPE(None, ctypes.c_int, ctypes.c_char_p, ctypes.c_void_p)(
    lambda kind, message, user: log.debug("libdc1394: %s", (message or b"").decode(errors="replace").strip())
)


def missing_library_error() -> InputError:
    return InputError(f"--camera dc1394 needs libdc1394, which is not installed: apt-get install {DEBIAN_PACKAGE}")


@functools.cache
def _open(soname: str) -> ctypes.CDLL:
    try:
        lib = ctypes.CDLL(soname)
    except OSError:
        found = ctypes.util.find_library("dc1394")
        if found is None:
            raise missing_library_error() from None
        try:
            lib = ctypes.CDLL(found)
        except OSError:
            raise missing_library_error() from None
    for name, (restype, argtypes) in PROTOTYPES.items():
        fn = getattr(lib, name)
        fn.restype, fn.argtypes = restype, argtypes
    handler = ctypes.cast(_LOG_HANDLER, ctypes.c_void_p)
    for kind in (LOG_ERROR, LOG_WARNING):
        lib.dc1394_log_register_handler(kind, handler, None)
    return lib


def load_library(soname: str | None = None) -> ctypes.CDLL:
    """The system's libdc1394 with its prototypes declared, loaded once; :class:`InputError` naming the Debian
    package when it is not installed. Capture calls it through this module, so tests can replace it."""
    return _open(soname or SONAME)


def error_text(lib, code: int) -> str:
    """libdc1394's name for an error code (``dc1394_error_get_string``), for one-line messages."""
    try:
        text = lib.dc1394_error_get_string(code)
    except Exception:  # a library that cannot name its error still gets the number reported
        text = None
    if isinstance(text, bytes):
        text = text.decode(errors="replace")
    return f"{text} ({code})" if text else f"error {code}"


def mode_name(mode: int) -> str:
    i = mode - VIDEO_MODE_MIN
    return VIDEO_MODE_NAMES[i] if 0 <= i < VIDEO_MODE_NUM else f"mode {mode}"


def coding_name(coding: int) -> str:
    i = coding - COLOR_CODING_MIN
    return COLOR_CODING_NAMES[i] if 0 <= i < COLOR_CODING_NUM else f"coding {coding}"


def is_format7(mode: int) -> bool:
    return VIDEO_MODE_FORMAT7_0 <= mode < VIDEO_MODE_MIN + VIDEO_MODE_NUM
