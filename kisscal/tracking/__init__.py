"""Trajectory generation: predictors, Kalman filter, gating, blending, gap filling, labels."""
