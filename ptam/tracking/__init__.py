"""The tracking thread (PTAM §5): map-point projection, patch search, robust pose, motion model, quality."""
