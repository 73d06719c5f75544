"""The mapping thread's algorithms: map initialisation, bundle adjustment, map growth (PTAM §6)."""
