"""How each AIST++ genre dances in the synthetic twin: energy, stepping, accents, move choices.

Pure data. One :class:`DanceStyle` per genre; :mod:`dancedata.synth.choreography` draws a
dancer's moves from it. Break and Street Jazz were calibrated against the real AIST++ motions
of those genres (docs/STORE.md, "The synthetic twin's motion"): root speed, per-joint rotation
spread, knee flexion range, foot heights and kinetic-feature magnitudes. The other genres sit
between those two by their usual character (Krump and Lock energetic, Pop and Lock sharp, House
stepping, Waack arm-led, Ballet Jazz kicks and turns); they were not fitted to real data.
Lengths are metres, angles radians, fractions of one beat where stated.
"""

from __future__ import annotations

from dataclasses import dataclass, field

# Arm key poses, left-arm convention (the right arm is mirrored): (elevation γ, swing β,
# twist, elbow flexion), radians. The arm direction in the torso frame is
# Rz(γ) Ry(β) x̂ = (cos β cos γ, cos β sin γ, −sin β): γ < 0 lowers it, β < 0 brings it forward.
ARM_POSES: dict[str, tuple[float, float, float, float]] = {
    "down": (-1.30, -0.15, 0.0, 0.45),
    "swing_fwd": (-1.05, -0.80, 0.2, 0.90),
    "swing_back": (-1.20, 0.55, -0.1, 0.35),
    "punch": (-0.10, -1.45, 0.3, 0.15),
    "guard": (-0.85, -0.70, 0.4, 1.95),
    "up": (1.30, -0.25, 0.0, 0.40),
    "spread": (0.10, 0.00, 0.0, 0.30),
    "reach_down": (-1.30, -1.25, 0.0, 0.15),
}


@dataclass(frozen=True)
class DanceStyle:
    """Per-genre parameters of the choreography (see the module docstring)."""

    energy: float  # scales travel, bounce and arm amplitudes
    step_prob: float  # chance that a beat carries a step
    travel_m: float  # typical distance the body travels with one step
    step_height_m: float  # swing-foot lift
    bounce_m: float  # pelvis dip on the beat
    attack: float  # fraction of a beat a pose change takes (smaller: sharper)
    sharp: float  # 0 eases into the pose, 1 hits it (full speed until the beat)
    kick_prob: float = 0.05  # per step: a kick or knee lift instead of a plain step
    squat_prob: float = 0.1  # per 2-beat block: a deep knee bend
    floor_prob: float = 0.0  # per 2-beat block: floor work (torso pitched, hands low)
    spin_prob: float = 0.0  # per floor beat: a fast spin on the floor
    floor_every_phrase: bool = False  # every phrase goes down once and spins there
    turn_prob: float = 0.1  # per step: a quarter or half turn
    lean_prob: float = 0.1  # per beat: lean back (hips forward, spine arched)
    arm_change_prob: float = 0.7  # per beat: a new arm pose
    arm_weights: dict[str, float] = field(default_factory=dict)


def _arms(**weights: float) -> dict[str, float]:
    base = {name: 1.0 for name in ARM_POSES if name != "reach_down"}
    base.update(weights)
    return base


STYLES: dict[str, DanceStyle] = {
    "gBR": DanceStyle(1.35, 0.75, 0.30, 0.12, 0.06, 0.45, 0.7, kick_prob=0.12, squat_prob=0.2,
                      floor_prob=0.2, spin_prob=0.4, floor_every_phrase=True, turn_prob=0.2,
                      arm_weights=_arms(guard=2.0, punch=1.5)),
    "gPO": DanceStyle(0.95, 0.45, 0.15, 0.06, 0.05, 0.25, 0.95, squat_prob=0.1,
                      arm_weights=_arms(guard=2.0, punch=2.0, spread=1.5)),
    "gLO": DanceStyle(1.15, 0.55, 0.22, 0.10, 0.06, 0.30, 0.85, kick_prob=0.15, squat_prob=0.2,
                      lean_prob=0.1,
                      arm_weights=_arms(up=2.0, punch=2.0, spread=1.5)),
    "gMH": DanceStyle(1.0, 0.6, 0.20, 0.08, 0.07, 0.45, 0.5, squat_prob=0.1,
                      arm_weights=_arms(swing_fwd=2.0, swing_back=2.0)),
    "gLH": DanceStyle(1.05, 0.6, 0.22, 0.09, 0.06, 0.40, 0.6, kick_prob=0.08, squat_prob=0.15,
                      arm_weights=_arms(guard=1.5, swing_fwd=1.5)),
    "gHO": DanceStyle(1.2, 0.9, 0.28, 0.10, 0.05, 0.55, 0.3, kick_prob=0.1, turn_prob=0.2,
                      arm_weights=_arms(swing_fwd=2.0, swing_back=2.0, down=2.0)),
    "gWA": DanceStyle(1.0, 0.4, 0.15, 0.06, 0.04, 0.30, 0.8, squat_prob=0.05, lean_prob=0.12,
                      arm_change_prob=0.95, arm_weights=_arms(up=3.0, spread=2.5, guard=2.0)),
    "gKR": DanceStyle(1.45, 0.65, 0.22, 0.14, 0.08, 0.30, 0.95, squat_prob=0.25, lean_prob=0.15,
                      arm_weights=_arms(punch=3.0, guard=2.0, spread=1.5)),
    "gJS": DanceStyle(0.65, 0.4, 0.18, 0.12, 0.04, 0.55, 0.4, kick_prob=0.15, squat_prob=0.1,
                      turn_prob=0.15, arm_weights=_arms(spread=2.0, up=1.5)),
    "gJB": DanceStyle(0.8, 0.55, 0.20, 0.10, 0.03, 0.60, 0.2, kick_prob=0.25, squat_prob=0.05,
                      turn_prob=0.25, arm_weights=_arms(spread=3.0, up=2.0)),
}  # fmt: skip
DEFAULT_GENRE = "gMH"


def style_of(genre: str | None) -> DanceStyle:
    """The style of an AIST++ genre code (``gBR``...); unknown or ``None``: Middle Hip-hop."""
    return STYLES.get(genre or DEFAULT_GENRE, STYLES[DEFAULT_GENRE])
