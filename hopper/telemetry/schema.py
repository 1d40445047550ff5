"""What a recording holds: its application id, timelines and signal fields."""

from __future__ import annotations

from hopper.layout import LEG_JOINTS

APPLICATION_ID = "hopper"
TIME = "sim_time"  # duration timeline: simulation time, monotonic across resets
HOP = "hop"  # sequence timeline: hops completed in this recording
SIGNALS_F32 = ("pitch_deg", "pitch_rate_deg_s", "wheel_rpm", "wheel_torque_nm")
SIGNALS_F16 = (*(f"{j}_deg" for j in LEG_JOINTS), *(f"{j}_torque_nm" for j in LEG_JOINTS), "foot_L_n", "foot_R_n")
SIGNALS = SIGNALS_F32 + SIGNALS_F16
