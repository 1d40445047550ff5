"""Data package: the dashboard's help, stylesheet, logo and theme, read with importlib.resources."""
