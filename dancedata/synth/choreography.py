"""A dancer's moves, beat by beat: where the feet land, how low the body goes, the arm poses.

Pure functions. :func:`plan_beats` draws, from a genre's :class:`~dancedata.synth.styles.DanceStyle`
and a seed, one key per beat: every key is the pose *reached on that beat* (time b · 60 / bpm
seconds; the synthetic music starts on a downbeat at t = 0), so pose changes arrive on the
music's beats. Basic pieces (``sBM``) repeat one 8-beat phrase, as AIST++'s basic dances repeat
one move; advanced pieces (``sFM``) mostly draw a new phrase every 8 beats and travel further.
:func:`hit_curve` turns the keys into per-frame values. Lengths metres, angles radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dancedata.synth.styles import ARM_POSES, DanceStyle

PHRASE_BEATS = 8
HALF_STANCE_M = 0.13  # half the distance between the feet when standing
FLOOR_DROP_M = 0.40  # pelvis drop in floor work
FLOOR_PITCH = 1.35  # forward pitch of the pelvis in floor work (≈77°)
SQUAT_DROP_M = 0.28
SQUAT_PITCH = 0.45
LEAN_PITCH = -0.25
MAX_TRAVEL_M = 0.4  # one step moves the body at most this far (before the sFM factor)
MAX_SPREAD_M = 0.8  # the feet are at most this far apart
STAGGER_M = 0.15  # spread of how far a landing foot is ahead of (or behind) the body
ARM_REACH = 0.55
CENTRE_M = np.array([0.0, 0.6])  # (x, z) the dancer comes back to (the cameras aim there)

_ARM_NAMES = tuple(ARM_POSES)
_MOVE_KEYS = ("step", "travel", "turn", "kick", "spin", "level", "arms", "torso", "accent",
              "height", "lean", "stagger")  # fmt: skip


@dataclass(frozen=True)
class BeatPlan:
    """Keys per beat b = 0..B−1 (the value reached at beat b)."""

    heading: np.ndarray  # (B,) facing yaw about +y from steps' turns
    spin_turn: np.ndarray  # (B,) yaw added by the spins so far (multiples of 2π)
    centre: np.ndarray  # (B, 2) body centre on the floor (x, z)
    feet: np.ndarray  # (B, 2, 2) ground point (x, z) of the left and right ankle
    step_foot: np.ndarray  # (B,) int: foot landing on beat b (0 left, 1 right, −1 none)
    step_height: np.ndarray  # (B,) swing-foot lift of that step
    kick: np.ndarray  # (B,) bool: the step is a kick (foot high and forward mid-swing)
    spin: np.ndarray  # (B,) bool: a full turn arriving on beat b, feet off the floor
    drop: np.ndarray  # (B,) pelvis drop below standing
    pitch: np.ndarray  # (B,) forward pitch of the pelvis
    arms: np.ndarray  # (B, 2, 4) arm key poses (ARM_POSES layout), left then right
    torso: np.ndarray  # (B, 3) spine flexion, twist, side bend (summed over the spine)
    accent: np.ndarray  # (B,) strength of the beat's accent (head and shoulder hit)


def _phrase(style: DanceStyle, rng: np.random.Generator, situation: str) -> dict[str, list]:
    """One 8-beat phrase of moves (relative: travel per step, turns, levels, poses)."""
    travel_scale = 2.0 if situation == "sFM" else 0.6
    levels = []
    for _ in range(PHRASE_BEATS // 2):
        r = rng.random()
        level = 2 if r < style.floor_prob else 1 if r < style.floor_prob + style.squat_prob else 0
        levels += [level, level]
    if style.floor_every_phrase and 2 not in levels:
        block = 2 * int(rng.integers(PHRASE_BEATS // 2))
        levels[block : block + 2] = [2, 2]
    # The forced spin comes on the second beat of a floor block, once the body is down.
    settled = [i for i in range(1, PHRASE_BEATS, 2) if levels[i] == 2]
    forced_spin = int(rng.choice(settled)) if style.floor_every_phrase else -1
    names = [n for n in _ARM_NAMES if n in style.arm_weights]
    weights = np.array([style.arm_weights[n] for n in names])
    weights = weights / weights.sum()
    moves: dict[str, list] = {key: [] for key in _MOVE_KEYS}
    arms = [ARM_POSES["down"], ARM_POSES["down"]]
    down = np.array(ARM_POSES["down"])
    for beat in range(PHRASE_BEATS):
        level = levels[beat]
        step = rng.random() < (style.step_prob if level < 2 else 0.6)
        spin = level == 2 and (rng.random() < style.spin_prob or beat == forced_spin)
        kick = step and level == 0 and rng.random() < style.kick_prob
        turn = 0.0
        turn_prob = style.turn_prob if situation == "sFM" else 0.0  # basic pieces face front
        if step and not spin and rng.random() < turn_prob:
            turn = rng.choice([-np.pi, -np.pi / 2, np.pi / 2, np.pi])
        distance = min(abs(rng.normal(style.travel_m, 0.4 * style.travel_m)), MAX_TRAVEL_M)
        distance *= travel_scale
        distance *= 0.5 if level == 2 else 1.0
        direction = rng.uniform(-np.pi, np.pi)
        if level == 2:
            pose = ARM_POSES["reach_down"]
            arms = (
                [pose, pose]
                if rng.random() < 0.6
                else [pose, ARM_POSES[str(rng.choice(names, p=weights))]]
            )
        elif beat == 0 or rng.random() < style.arm_change_prob:
            left = ARM_POSES[str(rng.choice(names, p=weights))]
            right = left if rng.random() < 0.4 else ARM_POSES[str(rng.choice(names, p=weights))]
            if left == ARM_POSES["swing_fwd"] and right == left:
                right = ARM_POSES["swing_back"]  # swing the arms in opposition
            arms = [left, right]
        moves["step"].append(step or spin)
        moves["travel"].append(distance * np.array([np.sin(direction), np.cos(direction)]))
        moves["turn"].append(2 * np.pi * rng.choice([-1, 1]) if spin else turn)
        moves["kick"].append(kick)
        moves["spin"].append(spin)
        moves["level"].append(level)
        # Poses are taken 55 % of the way from hanging arms; elbows vary the most.
        keyed = down + ARM_REACH * (np.array(arms) - down)
        jitter = rng.normal(0, 1, (2, 4)) * np.array([0.12 * style.energy] * 3 + [0.45])
        moves["arms"].append(keyed + jitter)
        torso = style.energy * np.array(
            [rng.normal(0.2, 0.2), rng.normal(0, 0.4), rng.normal(0, 0.2)]
        )
        lean = level == 0 and rng.random() < style.lean_prob
        if lean:  # arch back, neck behind the feet
            torso[0] = -rng.uniform(0.7, 1.0)
        moves["torso"].append(torso)
        moves["lean"].append(lean)
        moves["accent"].append((1.0 if beat % 2 == 0 else 0.7) * style.energy * rng.uniform(0.6, 1))
        moves["stagger"].append(rng.normal(0.0, STAGGER_M))  # one foot ahead of the other
        moves["height"].append(style.step_height_m * rng.uniform(1.2, 2.8))
    return moves


def plan_beats(
    n_beats: int, style: DanceStyle, rng: np.random.Generator, situation: str = "sBM"
) -> BeatPlan:
    """Keys for beats 0..``n_beats``−1: phrases drawn from ``style`` and laid end to end."""
    phrases = [_phrase(style, rng, situation)]
    heading = np.zeros(n_beats)
    centre = np.zeros((n_beats, 2))
    feet = np.zeros((n_beats, 2, 2))
    step_foot = np.full(n_beats, -1)
    height = np.zeros(n_beats)
    kick = np.zeros(n_beats, dtype=bool)
    spin = np.zeros(n_beats, dtype=bool)
    level = np.zeros(n_beats, dtype=int)
    lean = np.zeros(n_beats, dtype=bool)
    arms = np.zeros((n_beats, 2, 4))
    torso = np.zeros((n_beats, 3))
    accent = np.zeros(n_beats)
    spin_turn = np.zeros(n_beats)
    psi, spun, c = 0.0, 0.0, CENTRE_M.copy()
    side = np.array([1.0, -1.0])  # left foot on the body's +x side

    def lateral(yaw: float) -> np.ndarray:
        return np.array([np.cos(yaw), -np.sin(yaw)])

    ground = np.stack([c + s * HALF_STANCE_M * lateral(psi) for s in side])
    next_foot = int(rng.integers(2))
    for b in range(n_beats):
        k = b % PHRASE_BEATS
        if k == 0 and b > 0:
            fresh = situation == "sFM" and rng.random() < 0.75
            phrases.append(_phrase(style, rng, situation) if fresh else phrases[-1])
        moves = phrases[-1]
        level[b] = moves["level"][k]
        lean[b] = moves["lean"][k]
        arms[b] = moves["arms"][k]
        torso[b] = moves["torso"][k]
        accent[b] = moves["accent"][k]
        if b > 0 and moves["step"][k]:
            if moves["spin"][k]:
                spin[b] = True  # a full turn in place: centre and ground points come back
                spun += moves["turn"][k]
            else:
                psi += moves["turn"][k]
                # Travel, pulled back towards the centre so the dancer stays in view.
                c = c + moves["travel"][k] - 0.35 * (c - CENTRE_M)
                foot = next_foot
                width = HALF_STANCE_M * (1.6 if level[b] == 2 else 1.0)
                ahead = np.array([np.sin(psi), np.cos(psi)])  # facing direction on the floor
                ground[foot] = c + side[foot] * width * lateral(psi) + moves["stagger"][k] * ahead
                apart = ground[foot] - ground[1 - foot]  # legs only spread so far
                spread = float(np.linalg.norm(apart))
                if spread > MAX_SPREAD_M:
                    ground[foot] = ground[1 - foot] + apart * (MAX_SPREAD_M / spread)
                step_foot[b], height[b], kick[b] = foot, moves["height"][k], moves["kick"][k]
                next_foot = 1 - foot
        heading[b], spin_turn[b], centre[b], feet[b] = psi, spun, c, ground
    drop = np.select([level == 2, level == 1], [FLOOR_DROP_M, SQUAT_DROP_M], 0.0)
    pitch = np.select([level == 2, level == 1, lean], [FLOOR_PITCH, SQUAT_PITCH, LEAN_PITCH], 0.05)
    return BeatPlan(heading, spin_turn, centre, feet, step_foot, height, kick, spin, drop,
                    pitch, arms, torso, accent)  # fmt: skip


def beat_position(n_frames: int, fps: float, bpm: float) -> np.ndarray:
    """(F,) each frame's time in beats since t = 0."""
    return np.arange(n_frames) / fps * bpm / 60.0


def transition(beat_pos: np.ndarray, attack: float, sharp: float) -> tuple[np.ndarray, np.ndarray]:
    """(previous beat index, progress s in [0, 1]) per frame: the change towards the next beat's
    key starts ``attack`` beats before it and ends, at rest, on the beat. ``sharp`` mixes a
    smoothstep (0: speeds up and slows down evenly) with the hit s = 2v³ − v⁶ (1: top speed at
    74 % of the way, then a hard stop in the last quarter: the accent lands on the beat)."""
    b = np.floor(beat_pos).astype(np.int64)
    u = beat_pos - b
    v = np.clip((u - (1.0 - attack)) / attack, 0.0, 1.0)
    v3 = v * v * v
    return b, (1.0 - sharp) * v * v * (3.0 - 2.0 * v) + sharp * (2.0 * v3 - v3 * v3)


def hit_curve(keys: np.ndarray, beat_pos: np.ndarray, attack: float, sharp: float) -> np.ndarray:
    """Per-frame values moving from key b to key b+1 in the last ``attack`` of each beat
    (:func:`transition`); frames past the last key keep it. ``keys`` is (B, ...)."""
    keys = np.asarray(keys, dtype=np.float64)
    b, s = transition(beat_pos, attack, sharp)
    b = np.minimum(b, len(keys) - 1)
    nxt = np.minimum(b + 1, len(keys) - 1)
    s = s.reshape(s.shape + (1,) * (keys.ndim - 1))
    return keys[b] + (keys[nxt] - keys[b]) * s
