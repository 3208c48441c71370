"""Primitive settings like the real robot: records, TOML/CLI, the until-state-change mode,
actuation and pose noise."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from simlab.base.errors import ConfigError
from simlab.physics.drive import drive
from simlab.physics.motion import (
    PrimitiveParams,
    execute_primitive,
    noisy_pose,
    primitive_params_from_record,
)
from simlab.physics.world import World


def test_zero_noise_is_bit_identical_to_the_trajectories_before_the_noise_fields() -> None:
    # Values computed with the code before the mode/noise fields existed (same machine
    # arithmetic: PyBullet DIRECT is deterministic); any extra random draw would change them.
    # Regenerated once for the contact model without wheel spinning friction (the frame
    # tree rooted at base_footprint alone left them bit-identical). Stepped at 200 Hz, the
    # rate they were computed at (the default rate changed since; 200 Hz did not).
    s = drive("table_obstacles", 25, 7, progress=False, physics_hz=200.0)
    assert s.trail[-1].tolist() == [0.0800526453465296, 0.11383068306216383, 2.356174620899465]
    assert s.trail.sum(axis=0).tolist() == [0.9848365381034239, 0.42477611346907174,
                                            9.427881828633446]
    assert s.blocked == 4 and s.stepped_time == 29.73


def test_params_round_trip_through_json_and_toml(tmp_path: Path) -> None:
    p = PrimitiveParams(drive_time=0.8, mode="until_state_change", max_drive_time=2.0,
                        wheel_noise=0.05, wheel_noise_tick=0.02, slip=0.1, pose_noise_xy=0.01,
                        pose_noise_yaw=0.02, decision_latency=1.5)
    assert PrimitiveParams.from_json(json.loads(json.dumps(p.to_json()))) == p
    f = tmp_path / "p.toml"
    f.write_text(p.toml_text() + "\n[calibration]\nscore = 0.2\n")
    assert PrimitiveParams.from_toml(f) == p
    f.write_text("[primitives]\ndrive_time = 0.7\nwheel_nosie = 0.1\n")
    with pytest.raises(ConfigError, match=r"p\.toml: primitives\.wheel_nosie: unknown"):
        PrimitiveParams.from_toml(f)
    f.write_text("[primitives]\nslip = 1.0\n")
    with pytest.raises(ConfigError, match=r"primitives\.slip: must be < 1"):
        PrimitiveParams.from_toml(f)
    f.write_text("[primitives]\nmode = 'sometimes'\n")
    with pytest.raises(ConfigError, match=r"primitives\.mode"):
        PrimitiveParams.from_toml(f)
    f.write_text("drive_time = 0.7\n")
    with pytest.raises(ConfigError, match=r"primitives: missing table"):
        PrimitiveParams.from_toml(f)


def test_primitive_params_from_record_reads_manifests_and_refuses_others() -> None:
    p = PrimitiveParams(slow_speed=0.08)
    manifest = {"simulator": "physics", "parameters": {"primitive": p.to_json()}}
    assert primitive_params_from_record(manifest) == p
    assert primitive_params_from_record(manifest["parameters"]) == p
    assert primitive_params_from_record(p.to_json()) == p
    old = {k: v for k, v in p.to_json().items() if k not in ("mode", "slip")}  # older record
    assert primitive_params_from_record(old) == p
    assert primitive_params_from_record({"parameters": {}}) is None
    assert primitive_params_from_record(None) is None
    kinematic = {"simulator": "kinematic", "parameters": {"primitive": {"slow_speed": 0.1}}}
    assert primitive_params_from_record(kinematic) is None


def test_cli_flags_override_the_file(tmp_path: Path) -> None:
    import argparse

    from simlab.cli.collect import add_primitive_arguments, primitive_params_from_args

    parser = argparse.ArgumentParser()
    add_primitive_arguments(parser)
    assert primitive_params_from_args(parser.parse_args([])) is None
    f = tmp_path / "p.toml"
    f.write_text("[primitives]\ndrive_time = 0.9\nslow_speed = 0.05\n")
    args = parser.parse_args(["--primitives", str(f), "--drive-time", "0.6",
                              "--mode", "until_state_change", "--decision-latency", "1"])
    assert primitive_params_from_args(args) == PrimitiveParams(
        drive_time=0.6, slow_speed=0.05, mode="until_state_change", decision_latency=1.0)


def _grid_state(xy: np.ndarray) -> int:
    """States on a 0.2 m grid."""
    return math.floor(xy[0] / 0.2) * 1000 + math.floor(xy[1] / 0.2)


def test_until_state_change_stops_in_the_next_state_or_at_a_wall_or_timeout() -> None:
    p = PrimitiveParams(mode="until_state_change", max_drive_time=1.5)
    rng = np.random.default_rng(4)
    reasons = set()
    with World("table") as world:
        with pytest.raises(ConfigError, match="state_of"):
            execute_primitive(world, 0, rng, p)
        for a in rng.integers(0, 16, size=30):
            r = execute_primitive(world, int(a), rng, p, state_of=_grid_state)
            reasons.add(r.stop_reason)
            assert r.drive_duration <= p.max_drive_time + 1e-9
            if r.stop_reason == "state_change":
                assert _grid_state(r.pose_after[:2]) != _grid_state(r.pose_before[:2])
            if r.stop_reason == "blocked":
                assert r.blocked and r.drive_duration == 0.0
        # slow moves of 0.1 m/s cross a 0.2 m cell in at most 2 s: mostly state changes
    assert "state_change" in reasons and reasons <= {"state_change", "detector", "timeout",
                                                     "blocked"}


def _end_states(params: PrimitiveParams, n: int) -> np.ndarray:
    """Final x (1 cm bins) of ``n`` fast RIGHT moves from the same pose (world rebuilt)."""
    rng = np.random.default_rng(11)
    out = []
    with World("table") as world:
        for _ in range(n):
            world.reset((-0.3, 0.0, 0.0))
            r = execute_primitive(world, 11, rng, params)
            pose = noisy_pose(r.pose_after, params, rng)
            out.append(math.floor(pose[0] / 0.01))
    return np.asarray(out)


def _entropy(x: np.ndarray) -> float:
    _, counts = np.unique(x, return_counts=True)
    q = counts / counts.sum()
    return float(-(q * np.log2(q)).sum())


def test_noise_raises_next_state_entropy() -> None:
    quiet = _entropy(_end_states(PrimitiveParams(), 12))
    noisy = _entropy(_end_states(PrimitiveParams(wheel_noise=0.2, slip=0.5), 12))
    posed = _entropy(_end_states(PrimitiveParams(pose_noise_xy=0.03), 12))
    assert quiet == 0.0  # the noise-free primitive is deterministic from a rebuilt world
    assert noisy > 1.0 and posed > 1.0
