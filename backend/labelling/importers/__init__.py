"""Importers turning datasets and files into videos with frames (and labels)."""
