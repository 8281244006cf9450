"""3D reconstruction: stationary-ghost filter, epipolar matching, triangulation, grouping."""
