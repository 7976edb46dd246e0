"""Condition monitoring over long records (hosid monitor)."""
