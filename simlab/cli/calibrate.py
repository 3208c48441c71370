"""``simlab calibrate``: fit the primitive parameters so the simulated T matches a real one.

The options are the fields of :class:`simlab.calibration.command.CalibrateConfig`.
"""

from __future__ import annotations

import argparse
import math

HELP = "calibrate primitive parameters against a real transition count table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from simlab.calibration.command import CalibrateConfig

    CalibrateConfig.add_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from simlab.calibration.command import CalibrateConfig, calibrate_command
    from simlab.calibration.report import level_json

    done = calibrate_command(CalibrateConfig.from_args(args))
    r = done.result
    values = ", ".join(f"{n}={_value(getattr(r.params, n))}" for n in r.space.names)
    how = (f"confirmed on {r.config.confirm_seeds} fresh seed(s) among "
           f"{len({c.index for c in r.confirmed})} candidates" if r.confirmed
           else "screening only")
    print(f"winner: candidate #{r.best} of {len(r.candidates)} ({how}): {values}")
    tv = r.final.tv
    lv = level_json(r)
    fresh = (lv["fresh"] or {}).get("perfect_twin")
    level = ("" if lv["perfect_twin"] is None else
             f", a twin equal to the robot {_num(r.perfect_floor.median)}: "
             f"{lv['perfect_twin']:.2f}x"
             + ("" if fresh is None else f", {fresh:.2f}x on fresh twin walks"))
    print(f"TV distance {r.final.distance:.3f} (floor {_num(r.floor.median)}, matched "
          f"{_num(r.matched_floor.median)}{level}); the twin tried {tv.common} of "
          f"{tv.common + tv.real_only} real (s, a) pairs; argmax agreement "
          f"{_num(100 * r.agreement, '{:.0f}')} %")
    gap = r.final.gap
    if gap is not None:
        print(f"signature at the robot's visits, twin / robot: stays {_num(gap.self_share)} / "
              f"{_num(gap.self_share_real)}, entropy per action {_num(gap.entropy, '{:.2f}')} / "
              f"{_num(gap.entropy_real, '{:.2f}')} bits, outcomes per region TV "
              f"{_num(gap.regions)}")
    if r.contradictions is not None:
        print(r.contradictions.summary() + (" (report.md lists them, pairs.png draws them)"
                                            if r.contradictions.pairs else ""))
    if len(r.ensemble) > 1:
        print(f"twin ensemble: {len(r.ensemble)} confirmed candidates within sampling of the "
              "winner (report.md: how sure the twin is, field by field)")
    if r.transfer is not None:
        from simlab.calibration.report import policy_data, transfer_headline, transfer_overview

        ov = transfer_overview(r.transfer)
        ratios = [t["ratio"] for t in ov["twins"]]
        shown = ", ".join("never" if x is None else f"{x:.3f}" for x in ratios)
        print(f"transfer ({ov['goals']} goals): {transfer_headline(r)}; per twin seed "
              f"{shown}")
        need = policy_data(r)
        if need is not None:
            hours = "" if need["hours"] is None else f" ({need['hours']:.0f} h)"
            gain = ("more data do not improve the twins' policies" if need["flat"] else
                    f"the smallest size measured, already within {need['tolerance']} of "
                    "unlimited twin data" if need["below_measured"] else
                    f"bring a twin policy within {need['tolerance']} of unlimited twin data")
            print(f"policy data: {need['transitions']:,} twin transitions{hours} ({gain}; "
                  f"{need['limit']:.3f} x the optimum)")
    print("wrote " + ", ".join(str(p) for p in done.files.values()))
    return 0


def _num(x: float, fmt: str = "{:.3f}") -> str:
    return fmt.format(x) if math.isfinite(x) else "n/a"


def _value(v: object) -> str:
    return v if isinstance(v, str) else f"{v:.4g}"
