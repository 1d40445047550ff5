"""What a recording holds: its application id, timelines, signal fields and hop-table resolutions."""

from __future__ import annotations

from hopper.layout import LEG_JOINTS
from hopper.metrics import HopMetrics

APPLICATION_ID = "hopper"
TIME = "sim_time"  # duration timeline: simulation time, monotonic across resets
HOP = "hop"  # sequence timeline: hops completed in this recording
# The estimate is what the controller used (SimConfig.sensing "realistic": the IMU's attitude
# estimate; "ideal": the truth), beside the truth.
# wheel_capacity_pct: the wheel's momentum, (I_w + armature) * speed, as a signed percentage of its
# capacity (I_w + armature) * no-load speed: the headroom left for a flight either way.
SIGNALS_F32 = (
    "pitch_deg",
    "pitch_rate_deg_s",
    "wheel_rpm",
    "wheel_torque_nm",
    "pitch_est_deg",
    "pitch_rate_est_deg_s",
    "wheel_capacity_pct",
    "inject_torque_nm",  # the excitation added to the wheel torque (0 unless a measurement runs)
    "inject_ref_deg",  # the excitation added to the pitch reference
    "wheel_cmd_nm",  # the wheel torque the controller asked, before the motor's delay line and speed envelope
)
SIGNALS_F16 = (*(f"{j}_deg" for j in LEG_JOINTS), *(f"{j}_torque_nm" for j in LEG_JOINTS), "foot_L_n", "foot_R_n")
SIGNALS = SIGNALS_F32 + SIGNALS_F16

# Decimals each float HopMetrics field is rounded to in the hop table: a dataframe view prints a
# float64 in full, and 0.812345678901234 m says no more than 0.812 m.
HOP_DECIMALS = {
    "distance_m": 3,  # 1 mm
    "apex_height_m": 3,
    "flight_time_s": 3,  # 1 ms
    "stance_time_s": 3,
    "peak_pitch_deg": 2,  # 0.01 deg
    "rms_pitch_rate_deg_s": 1,  # 0.1 deg/s
    "landing_pitch_deg": 2,
    "saturation_time_s": 3,
    "peak_wheel_rpm": 0,  # 1 rpm
    "liftoff_momentum": 4,  # 1e-4 N m s
    "touchdown_time_s": 3,
    "response_start_s": 3,  # the response (hopper.metrics.ResponseMetrics), from the kick or the liftoff
    "response_peak_deg": 2,
    "overshoot_deg": 2,
    "settling_time_s": 3,
    "peak_wheel_torque_nm": 2,  # 0.01 N m
    "peak_momentum_pct": 1,  # 0.1 % of the capacity
    "landing_error_deg": 2,
    "wheel_energy_j": 2,  # 0.01 J (hopper.control.energy)
    "leg_energy_j": 2,
    "cost_of_transport": 3,  # NaN for a hop in place
}


def hop_values(hop: HopMetrics) -> dict[str, float | int | bool]:
    """One hop-table row: `hop`'s fields, the floats rounded to HOP_DECIMALS (KeyError names a new
    float field without a resolution); `+ 0.0` turns a rounded -0.0 into 0.0."""
    return {
        name: round(value, HOP_DECIMALS[name]) + 0.0 if isinstance(value, float) else value
        for name, value in hop.as_dict().items()
    }
