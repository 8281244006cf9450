"""Figures and the HTML session report."""
