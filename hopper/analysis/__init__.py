"""Analysis of the flight loop: the plant linearized from MuJoCo, loop margins and poles, gain design,
the loop identified from a kick, and the recoverable envelope."""
