"""Training and evaluation of detection models (classical grids, a torch temporal model)."""
