"""ptam: Parallel Tracking and Mapping (Klein & Murray 2007) and its extensions, in Python."""

__version__ = "0.1.0"
