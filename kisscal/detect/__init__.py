"""Blob detection: run-length pixel grouping, noise removal, merge/split tests, centroids."""
