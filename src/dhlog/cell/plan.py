"""What a measurement plan will give, before going to the cell (``dhlog plan``).

The plan — a protocol on the nominal robot, with the tracker's noise — is simulated once on the
nominal (the robot as planned) and identified as ``dhlog process --model geometric`` would; the
covariance of that fit, rescaled by its own χ²/dof to the stated noise, is the inverse of the
Fisher information of the plan's poses under the noise model (the first-order covariance the
maximum-likelihood fit reaches; `tests/test_uncertainty.py` holds the reported σ to 15 % of the
empirical spread). From it: the σ of every DH parameter (in the shown form: Hayati rows where a
pair is nearly parallel), what the plan cannot determine, and the predicted FK σ at random joint
vectors within the limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from dhlog.errors import InputError
from dhlog.geometry._checks import FloatArray
from dhlog.model.noise import NoiseModel
from dhlog.model.robots import Robot
from dhlog.simulator.config import SimulationConfig
from dhlog.simulator.session import simulate_session

#: Joint vectors (seeded, uniform within the limits) the FK σ is predicted at.
WORKSPACE_POINTS = 300


@dataclass
class Plan:
    """The predicted σ of each shown DH row (θ, d or β, a, α; NaN where fixed) with the rows'
    forms and the reasons parameters are fixed; the predicted FK σ (m, 3-D) at
    :data:`WORKSPACE_POINTS` joint vectors within the limits; the samples and poses the plan
    measures."""

    rows_std: FloatArray
    forms: list[str]
    fixed: list[str]
    fk_sd: FloatArray
    samples: int
    poses: int
    noise: float
    #: random poses drawn but left out: the target beyond the tracker's reach
    out_of_range: int = 0
    #: the noise model planned with, in words
    noise_model: str = ""

    def document(self, robot: str) -> dict[str, object]:
        """The plan as JSON (SI units; ``null`` where a parameter is fixed)."""
        sd = self.fk_sd
        return {
            "format": "dhlog-plan/1",
            "robot": robot,
            "samples": self.samples,
            "poses": self.poses,
            "poses_out_of_range": self.out_of_range,
            "noise_m": self.noise,
            "noise_model": self.noise_model,
            "rows": [
                {
                    "form": form,
                    "std": {
                        name: None if not np.isfinite(v) else float(v)
                        for name, v in zip(
                            (
                                "theta_rad",
                                "hayati_beta_rad" if form == "hayati" else "d_m",
                                "a_m",
                                "alpha_rad",
                            ),
                            row,
                            strict=True,
                        )
                    },
                }
                for row, form in zip(self.rows_std, self.forms, strict=True)
            ],
            "fixed": self.fixed,
            "fk_std_m": {
                "points": int(sd.size),
                "rms": math.sqrt(float(np.mean(sd**2))),
                "p95": float(np.percentile(sd, 95)),
                "max": float(sd.max()),
            },
        }


@dataclass(frozen=True)
class Tracker:
    """Where the tracker stands and what it reaches: the station (m, 3) in the robot's base
    frame (its axes the base's), the range of distances (m) it measures; ``model``: its noise
    (radial, transverse, transverse per metre; m) in place of an isotropic σ."""

    station: tuple[float, float, float]
    reach: tuple[float, float] = (0.0, math.inf)
    model: tuple[float, float, float] | None = None

    def in_reach(self, robot: Robot, Q: FloatArray) -> NDArray[np.bool_]:
        """Per joint vector of ``Q`` (m, n): the nominal's target within the tracker's range."""
        from dhlog.model.fk import fk_point

        p = fk_point(robot.table, Q, robot.tool_point, T_base=robot.T_base)
        distance = np.linalg.norm(p - np.asarray(self.station), axis=1)
        return np.asarray((distance >= self.reach[0]) & (distance <= self.reach[1]))

    def measurement_pose(self) -> FloatArray:
        """T_measurement_robot: the tracker's frame at the station, axes along the base's."""
        T = np.eye(4)
        T[:3, 3] = -np.asarray(self.station)
        return T

    def described(self, isotropic: float) -> str:
        """The noise planned with and where the tracker stands, in words."""
        where = "at ({:g}, {:g}, {:g}) mm from the base".format(*(1e3 * np.array(self.station)))
        if self.model is None:
            return f"isotropic σ {isotropic * 1e3:g} mm, tracker {where}"
        radial, transverse, per_m = (1e6 * v for v in self.model)
        return (
            f"tracker (radial {radial:.1f} µm, transverse {transverse:.1f} µm + {per_m:.1f} "
            f"µm/m) {where}"
        )

    def noise(self, isotropic: float) -> NoiseModel:
        """The noise model of the measured targets in the tracker's frame."""
        if self.model is None:
            return NoiseModel(sigma=isotropic)
        radial, transverse, per_m = self.model
        return NoiseModel("tracker", radial=radial, transverse=transverse, transverse_per_m=per_m)


def plan_session(robot: Robot, cfg: SimulationConfig, tracker: Tracker | None = None) -> Plan:
    """The plan ``cfg`` (protocol, counts, noise) on ``robot`` as its nominal; with
    ``tracker``, the robot placed in front of it, its noise model, and random poses whose target
    is out of its range left out (counted)."""
    from dhlog.identify.check.validate import fk_prediction_std
    from dhlog.identify.fit.leaveout import pose_groups
    from dhlog.identify.joints.sweeps import samples_with_encoders
    from dhlog.identify.model.select import ModelRequest
    from dhlog.identify.run import ProcessOptions, process_data
    from dhlog.io.dhfile import DHModel
    from dhlog.io.memory import log_data_from_session
    from dhlog.present.console import held_lines
    from dhlog.result.document import display_rows

    if cfg.perturb_length or cfg.perturb_angle:
        raise InputError("a plan is made on the nominal robot; leave the perturbations out.")
    if cfg.noise <= 0:
        raise InputError("a plan needs the tracker's noise (> 0) to predict what it gives.")
    out_of_range = 0
    T_mr = None
    pipeline = None
    known = cfg.noise
    if tracker is not None:
        T_mr = tracker.measurement_pose()
        if cfg.protocol == "random-poses":
            from dhlog.simulator.protocols import random_poses

            home = np.clip(np.zeros(robot.n), robot.limits[:, 0], robot.limits[:, 1])
            Q = random_poses(robot, cfg, home)
            inside = tracker.in_reach(robot, Q)
            out_of_range = int((~inside).sum())
            if not inside.any():
                raise InputError(
                    f"no pose of the plan puts the target within the tracker's range "
                    f"({tracker.reach[0]:g}–{tracker.reach[1]:g} m from the station); move the "
                    "station or widen the range."
                )
            cfg = replace(cfg, pose_list=tuple(tuple(float(v) for v in q) for q in Q[inside]))
        if tracker.model is not None:
            from dhlog.io.pipeline import pipeline_by_name

            cfg = replace(cfg, tracker_model=tracker.model)
            shipped = pipeline_by_name("ros2_tracker")
            assert shipped is not None
            pipeline = replace(shipped, noise=tracker.noise(cfg.noise))
            radial, transverse, per_m = tracker.model  # the base plane: an equivalent σ
            t = transverse + per_m * float(np.linalg.norm(tracker.station))
            known = math.sqrt((radial**2 + 2 * t**2) / 3)
    session = simulate_session(robot, cfg, T_measurement_robot=T_mr)
    names = tuple(f"joint_{i + 1}" for i in range(robot.n))
    nominal = DHModel(robot.table, robot.T_base, robot.tool_point, names, robot.name)
    result = process_data(
        log_data_from_session(session, pipeline),
        ProcessOptions(nominal=nominal, model=ModelRequest("geometric"), known_noise=known),
    )
    if result.parked:  # a run would hold it at the nominal: the plan does not identify it
        still = ", ".join(f"joint {k + 1}" for k in result.parked)
        raise InputError(
            f"this plan never moves {still}: a session like it holds that row at the nominal "
            "and identifies the rest; move every joint (sweeps or more varied poses)."
        )
    if not result.complete or result.whole is None:
        missing = ", ".join(f"joint {j.index} ({j.reason})" for j in result.failed)
        raise InputError(
            f"this plan does not identify every joint: {missing or 'the whole-model fit failed'};"
            " move every joint (sweeps or more varied poses)."
        )
    scale = 1.0 / math.sqrt(max(result.whole.chi2_dof, 1e-300))
    rows = display_rows(result, "m")
    rows_std = np.array(
        [
            [math.nan if r.held[k] else float(r.stds[k] or 0.0) * scale for k in range(4)]
            for r in rows
        ]
    )
    Q = np.random.default_rng(0).uniform(
        robot.limits[:, 0], robot.limits[:, 1], (WORKSPACE_POINTS, robot.n)
    )
    _, Qs, _ = samples_with_encoders(result.segmentation)
    return Plan(
        rows_std=rows_std,
        forms=[r.form for r in rows],
        fixed=held_lines(result, rows),
        fk_sd=fk_prediction_std(result, Q) * scale,
        samples=int(Qs.shape[0]),
        poses=int(np.unique(pose_groups(Qs)).size),
        noise=cfg.noise,
        out_of_range=out_of_range,
        noise_model=(
            f"isotropic σ {cfg.noise * 1e3:g} mm"
            if tracker is None
            else tracker.described(cfg.noise)
        ),
    )


#: A candidate pose whose spatial Jacobian's smallest singular value is below this (m/rad, a
#: mixed but robot-sized scale) is too near a singularity to be measured.
NEAR_SINGULAR = 1e-3


@dataclass
class Selection:
    """The poses chosen (indices into the candidates), the candidates left out as near a
    singularity, and the predicted FK σ RMS (m) over the workspace of the chosen poses and of
    as many drawn at random (seeded) from the usable candidates."""

    chosen: list[int]
    singular: int
    fk_sd_chosen: float
    fk_sd_random: float
    #: candidates left out as beyond the tracker's range
    out_of_range: int = 0


def select_poses(
    robot: Robot,
    candidates: FloatArray,
    count: int,
    noise: float,
    tracker: Tracker | None = None,
) -> Selection:
    """The ``count`` candidate poses that maximise the information about the whole model
    (D-optimal: each step adds the pose that most increases ``log det`` of the Fisher
    information, by the matrix determinant lemma), the model being the nominal's axes and tool
    point; a position target, isotropic noise ``noise`` or, with ``tracker``, its noise model
    along the line of sight from its station, and candidates beyond its range left out."""
    from dhlog.identify.fit.axismodel import AxisModel, ParameterLayout
    from dhlog.identify.fit.prediction import predict
    from dhlog.model.fk import spatial_jacobian

    singular = np.array(
        [
            np.linalg.svd(spatial_jacobian(robot.table, q, T_base=robot.T_base), compute_uv=False)[
                -1
            ]
            < NEAR_SINGULAR
            for q in candidates
        ]
    )
    far = ~tracker.in_reach(robot, candidates) if tracker is not None else np.zeros_like(singular)
    usable = ~singular & ~far
    index = np.flatnonzero(usable)
    if index.size < count:
        raise InputError(
            f"--select {count}: only {index.size} of the {len(candidates)} candidates are usable "
            f"({int(singular.sum())} near a singularity, {int((far & ~singular).sum())} beyond "
            "the tracker's range); give more candidates or select fewer."
        )
    ref = np.clip(np.zeros(robot.n), robot.limits[:, 0], robot.limits[:, 1])
    model = AxisModel.of_table(robot.table, ref, robot.tool_point, robot.T_base)
    layout = ParameterLayout.of(model.types)
    bases = model.bases()
    P, J = predict(model, candidates[index], layout, bases)
    assert J is not None
    if tracker is None or tracker.model is None:
        J = J / noise
    else:  # whitened along each line of sight: W with WᵀW = C⁻¹
        W = replace(tracker.noise(noise), station=tracker.station).whiten(P, noise)
        J = np.einsum("kij,kjp->kip", W, J)
    scale = np.sqrt(np.einsum("kij,kij->j", J, J)) + 1e-30  # columns of comparable size
    Js = J / scale
    info = 1e-9 * np.eye(layout.size)
    chosen: list[int] = []
    for _ in range(count):
        inv = np.linalg.inv(info)
        A = Js @ inv  # (k, 3, p)
        G = np.einsum("kip,kjp->kij", A, Js) + np.eye(3)
        gain = np.linalg.slogdet(G)[1]
        gain[chosen] = -np.inf
        best = int(np.argmax(gain))
        chosen.append(best)
        info = info + Js[best].T @ Js[best]

    Q = np.random.default_rng(0).uniform(
        robot.limits[:, 0], robot.limits[:, 1], (WORKSPACE_POINTS, robot.n)
    )
    _, Jw = predict(model, Q, layout, bases)
    assert Jw is not None
    Jw = Jw / scale

    def fk_sd(picked: list[int]) -> float:
        fisher = sum((Js[k].T @ Js[k] for k in picked), 1e-9 * np.eye(layout.size))
        var = np.einsum("mij,jk,mik->m", Jw, np.linalg.inv(fisher), Jw)
        return float(np.sqrt(np.mean(np.clip(var, 0.0, None))))

    drawn = list(np.random.default_rng(1).choice(index.size, count, replace=False))
    return Selection(
        [int(index[k]) for k in chosen],
        int(singular.sum()),
        fk_sd(chosen),
        fk_sd([int(k) for k in drawn]),
        int((far & ~singular).sum()),
    )
