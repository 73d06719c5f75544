"""The rerun viewer: an observer of the running system that logs from its own thread; tracking and mapping never
import it. ``viz.viewer.Viewer`` does the logging, ``viz.sinks.open_recording`` chooses where it goes (the native
viewer, an ``.rrd`` file, a web viewer on 127.0.0.1), ``viz.state`` names the tracking states. The submodules are
imported explicitly so that runs without a viewer never load rerun."""
