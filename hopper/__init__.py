"""Lunar reaction-wheel hopper: model, controller, phases, metrics and telemetry (no UI)."""
