"""Observations made from images: automatic matching, snapping, digitising, display copies."""
