"""DLT calibration: 11-parameter DLT, MDLT, rod recognition, projection, decomposition."""
