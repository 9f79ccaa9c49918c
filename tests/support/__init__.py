"""Helpers the tests and benchmarks share: simulated scenes and images, comparisons, hostile-input
checks, mounts, paths, processing and qgis_process runners, digitising and snapping drivers.
Test modules import shared helpers and fixtures from here, never from another test module."""
