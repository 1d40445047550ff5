"""Experiments at scale: sweep specs, episodes run by reusable workers, executors (local or Ray), Parquet,
tuning, the stress battery and the league of controllers."""
