"""Measurements that print figures (performance is measured here, never asserted in tests)."""
