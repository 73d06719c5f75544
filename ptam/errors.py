"""User-facing errors. The CLI prints ``str(error)`` as one line and exits with code 2."""


class PtamError(Exception):
    """Bad input or environment: a missing file, an invalid calibration, an unknown config key."""


class InputError(PtamError):
    """Input data (files, devices, datasets) that cannot be used."""


class ConfigError(PtamError):
    """A configuration key or value that is not valid."""
