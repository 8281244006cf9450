"""Reading and writing: session config, images, parameter files, C3D/TRC/CSV export."""
