"""Adaptive estimators, min-max covers and persistent-excitation diagnostics (uses physics)."""
