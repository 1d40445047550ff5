"""Data package: the robot's MJCF model (hopper.xml), read with importlib.resources."""
