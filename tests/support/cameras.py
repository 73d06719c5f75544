"""One camera of each model, with distortion, shared by the camera and kernel tests."""

from ptam.camera import FovCamera, PinholeCamera, RadTanCamera

W, H = 640, 480
CAMERAS = {
    "fov": FovCamera(W, H, 384.0, 386.0, 319.5, 239.5, 0.9),
    "pinhole": PinholeCamera(W, H, 500.0, 505.0, 320.2, 241.7),
    "radtan": RadTanCamera(W, H, 460.0, 462.0, 318.0, 243.0, -0.28, 0.07, 0.0008, -0.0005, 0.0),
}
