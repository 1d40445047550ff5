"""Live browser dashboard (viser) for the lunar hopper simulation."""
