"""Hopper logs: one schema (schema.Log), readers for CSV, MCAP and our own .rrd."""
