"""Synthetic scenes with known truth (sibling of core/: imports core, core never imports it)."""
