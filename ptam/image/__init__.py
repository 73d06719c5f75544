"""Image layer: pyramid, FAST corners, Shi-Tomasi score (PTAM §4, §5.1, §6.2)."""
