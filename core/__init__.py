"""Numeric core of Pushbroom Adjust.

Plain Python on numpy, scipy, pyproj and GDAL: nothing here imports qgis or Qt,
so every module can run headless (tests, scripts, other tools).
"""
