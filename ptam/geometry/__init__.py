"""Rigid-body and similarity geometry: SE(3)/SO(3), Sim(3) alignment, triangulation."""
