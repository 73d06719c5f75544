"""The map: keyframes, points and measurements as arrays, and the immutable snapshot the tracker reads (PTAM §4)."""
