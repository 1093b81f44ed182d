"""Gymnasium environments and wrappers (uses physics and estimation)."""
