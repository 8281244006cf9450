"""Grid linearisation: lattice indexing, primary/optimal grid, 4th-order polynomial fit."""
