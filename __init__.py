"""Pushbroom Adjust QGIS plugin.

Imports nothing at module level, so that ``core`` can be used (and tested) without QGIS.
"""


def classFactory(iface):  # noqa: N802 (QGIS plugin entry point)
    from .plugin import PushbroomAdjustPlugin
    return PushbroomAdjustPlugin(iface)
