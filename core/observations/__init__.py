"""Observations: ground control and check points, tie points, control lines, and the table helpers they
share."""
