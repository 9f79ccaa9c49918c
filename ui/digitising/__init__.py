"""The digitising dock: control lines drawn on the raw image (see dock.py)."""
