"""Labelling workspace: video importers, annotation segments, review, export, agreement."""
