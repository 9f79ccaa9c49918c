"""Helpers the tests share: simulated scenes and images, comparisons, hostile-input checks, mounts."""
