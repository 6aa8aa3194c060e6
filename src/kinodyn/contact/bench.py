"""``kinodyn bench contact``: Table 2 for the avatar scenarios, figure 7's hand phases, the narrow phase
beside coal and python-fcl, and CCD beside ikpy.

Everything runs on one core (numba pinned to one thread); times are the thread's CPU time, so other
work on the machine does not inflate them. Per scenario (``two_arms``, ``self_collision``,
``two_arms_leg``, ``arm_in_corner``, and ``walk_into_wall`` when its CMU walk is found through
``$KINODYN_MOCAP`` or beside the checkout; a note says when it was skipped, and the aggregates then
leave it out): frames, mean and slowest frame time, joints
adjusted by IK per frame, CCD iterations per frame, IK share of the frame time, overlapping pairs per
frame, collision-query share (Table 2's columns). ``max_penetration_mm`` is measured afresh on the
resolved motions against the fixed objects; ``limit_violations`` counts chain joints outside their
limits or reach cones in any frame where IK solved (or held) that chain. The narrow phase is timed and
checked on analytic cases (sphere, box and capsule pairs at known depths, and a sphere on a piece of
a CoACD-decomposed mesh) for
MuJoCo's ``mj_geomDistance`` (kinodyn's choice), coal and python-fcl, each on the same geometry. CCD is
timed beside ikpy on the same arm chain and goals.
"""

from __future__ import annotations

import time

import numpy as np

from kinodyn.bench import BenchResult

SCENARIOS = ("two_arms", "self_collision", "two_arms_leg", "arm_in_corner")
#: scenarios that play motion capture, run when the data is found (``$KINODYN_MOCAP``)
MOCAP_SCENARIOS = ("walk_into_wall",)
DEPTHS = (0.005, 0.02, 0.05, 0.09)


def _scenes(res: BenchResult) -> list:
    """The scenes to run: the avatar scenarios, those with motion capture when it is found, the hand."""
    from kinodyn.contact.command import with_motion
    from kinodyn.contact.scenefile import load_scene, scenario_path
    from kinodyn.errors import KinodynError

    out = [load_scene(scenario_path(n)) for n in SCENARIOS]
    for name in MOCAP_SCENARIOS:
        try:
            out.append(with_motion(load_scene(scenario_path(name))))
        except KinodynError as e:
            res.notes[f"skipped_{name}"] = str(e)
    return out + [load_scene(scenario_path("hand"))]


def _scenarios(res: BenchResult, progress) -> None:
    from kinodyn.contact.command import summary
    from kinodyn.contact.fix import penetration_before
    from kinodyn.contact.simulate import ContactSimulation
    from kinodyn.ik import ccd

    worst_mean, worst_frame, pen, bad = 0.0, 0.0, 0.0, 0
    ccd.warm_up()  # the IK kernels too, which the first frames (no contact yet) never call
    for scene in _scenes(res):
        name = scene.name
        sim = ContactSimulation(scene)
        for f in range(3):  # load the compiled kernels before timing
            sim.frame(f, {})
        sim = ContactSimulation(scene)
        r = sim.run(progress=progress)
        s = summary(r)
        res.add(f"frame_ms_{name}", s["frame_ms_mean"], "ms")
        res.add(f"frame_ms_worst_{name}", s["frame_ms_max"], "ms")
        res.add(f"frames_{name}", s["frames"], "frames")
        worst_mean, worst_frame = max(worst_mean, s["frame_ms_mean"]), max(worst_frame, s["frame_ms_max"])
        if name == "hand":
            from kinodyn.contact.motions import HAND_PHASES

            for k, ph in enumerate(HAND_PHASES):
                sel = r.frames["phase"] == k
                res.add(f"frame_ms_hand_{ph}", r.frames["frame_ms"][sel].mean(), "ms")
            res.add("ball_collisions_hand", s["collisions"], "impulses")
            continue
        res.add(f"fallback_frames_{name}", s["fallback_frames"], "frames")
        for key, unit in (("joints_per_frame", "joints"), ("iterations_per_frame", "iterations"),
                          ("ik_share", "fraction"), ("pairs_per_frame", "pairs"), ("query_share", "fraction")):
            res.add(f"{key}_{name}", s[key], unit)
        pen = max(pen, float(penetration_before(r.motion, scene).max()))
        av = sim.avatar
        lims = [ccd.chain_limits(av.limits, av.cone_axes, av.cone_points, c) for c in av.chains]
        for f, chains in enumerate(r.solved):
            for c in chains:
                bad += int((~ccd.limits_hold(r.motion.local_rot[f, av.chains[c]], lims[c])).sum())
    res.add("frame_ms_max", worst_mean, "ms")
    res.add("frame_ms_worst", worst_frame, "ms")
    res.add("max_penetration_mm", pen * 1e3, "mm")
    res.add("limit_violations", bad, "joint-frames")


def _cases():
    """(name, moving piece, its position, fixed piece, expected depth) of the analytic cases."""
    from kinodyn.contact import meshes
    from kinodyn.contact import setting as S

    v, f = meshes.prism([[0, 0], [1, 0], [1, 0.2], [0.2, 0.2], [0.2, 1], [0, 1]], 1.0)
    arm = max(meshes.decompose(v, f, name="bracket"), key=lambda p: np.ptp(p[:, 0]))  # the horizontal arm
    big = S.box([0.5, 0.5, 0.5])
    out = []
    for d in DEPTHS:
        out.append(("sphere_box", S.sphere(0.1), [0.1, -0.2, 0.5 + 0.1 - d], big, d))
        out.append(("box_box", S.box([0.2, 0.2, 0.2]), [0.05, 0.1, 0.5 + 0.2 - d], big, d))
        out.append(("capsule_box", S.capsule(0.05, 0.2, quat=[np.sqrt(0.5), 0, np.sqrt(0.5), 0]),
                    [0.0, 0.1, 0.5 + 0.05 - d], big, d))
        out.append(("sphere_mesh_piece", S.sphere(0.1), [0.6, 0.0, 0.2 + 0.1 - d], S.hull(arm), d))
    return out


def _kinodyn_depth(cases, repeats):
    from kinodyn.contact import setting as S
    from kinodyn.contact.collide import CollisionWorld

    errs, times = [], []
    for _, moving, pos, fixed, d in cases:
        w = CollisionWorld([S.SceneObject("a", "driven", "wood", (moving,), pos=pos),
                            S.SceneObject("b", "fixed", "wood", (fixed,))])
        t0 = time.thread_time()
        for _ in range(repeats):
            dist, _ = w.distance(1, 0, 0.0)
        times.append((time.thread_time() - t0) / repeats)
        errs.append(abs(-dist - d))
    return np.array(errs), np.array(times)


def _coal_geom(piece):
    import coal

    s = piece.size
    if piece.shape == "sphere":
        return coal.Sphere(s[0])
    if piece.shape == "box":
        return coal.Box(2 * s[0], 2 * s[1], 2 * s[2])
    if piece.shape == "capsule":
        return coal.Capsule(s[0], 2 * s[1])
    pts = coal.StdVec_Vec3s()
    for p in piece.vertices:
        pts.append(np.asarray(p, float))
    return coal.Convex.convexHull(pts, False, "")


def _coal_depth(cases, repeats):
    import coal

    from kinodyn.math import quat

    errs, times = [], []
    for _, moving, pos, fixed, d in cases:
        ga, gb = _coal_geom(moving), _coal_geom(fixed)
        ta = coal.Transform3s(quat.to_matrix(moving.quat), np.asarray(pos, float) + moving.pos)
        tb = coal.Transform3s()
        req = coal.CollisionRequest()
        req.enable_contact = True
        t0 = time.thread_time()
        for _ in range(repeats):
            res = coal.CollisionResult()
            coal.collide(ga, ta, gb, tb, req, res)
        times.append((time.thread_time() - t0) / repeats)
        errs.append(abs(abs(res.getContact(0).penetration_depth) - d) if res.isCollision() else d)
    return np.array(errs), np.array(times)


def _fcl_geom(piece):
    import fcl
    from scipy.spatial import ConvexHull

    s = piece.size
    if piece.shape == "sphere":
        return fcl.Sphere(s[0])
    if piece.shape == "box":
        return fcl.Box(2 * s[0], 2 * s[1], 2 * s[2])
    if piece.shape == "capsule":
        return fcl.Capsule(s[0], 2 * s[1])
    tri = ConvexHull(piece.vertices).simplices
    return fcl.Convex(piece.vertices, len(tri), np.hstack([np.full((len(tri), 1), 3), tri]).ravel())


def _fcl_depth(cases, repeats):
    import fcl

    from kinodyn.math import quat

    errs, times = [], []
    for _, moving, pos, fixed, d in cases:
        oa = fcl.CollisionObject(_fcl_geom(moving), fcl.Transform(quat.to_matrix(moving.quat),
                                                                  np.asarray(pos, float) + moving.pos))
        ob = fcl.CollisionObject(_fcl_geom(fixed), fcl.Transform())
        req = fcl.CollisionRequest(enable_contact=True, num_max_contacts=1)
        t0 = time.thread_time()
        for _ in range(repeats):
            res = fcl.CollisionResult()
            fcl.collide(oa, ob, req, res)
        times.append((time.thread_time() - t0) / repeats)
        errs.append(abs(res.contacts[0].penetration_depth - d) if res.contacts else d)
    return np.array(errs), np.array(times)


def _narrow(res: BenchResult, quick: bool) -> None:
    cases = _cases()
    repeats = 200 if quick else 2000
    for key, fn in (("kinodyn", _kinodyn_depth), ("coal", _coal_depth), ("fcl", _fcl_depth)):
        try:
            errs, times = fn(cases, repeats)
        except ImportError:
            res.notes[f"narrow_{key}"] = "not installed"
            continue
        prefix = "" if key == "kinodyn" else f"{key}_"
        res.add(f"{prefix}depth_error_mm", errs.max() * 1e3, "mm")
        res.add(f"{prefix}depth_us_per_pair", times.mean() * 1e6, "us")
        for case in ("sphere_box", "box_box", "capsule_box", "sphere_mesh_piece"):
            sel = np.array([c[0] == case for c in cases])
            res.add(f"{prefix}depth_error_mm_{case}", errs[sel].max() * 1e3, "mm")
        if key != "kinodyn":
            res.baseline[f"{key}_depth_error_mm"] = float(errs.max() * 1e3)


def _ik(res: BenchResult, quick: bool) -> None:
    from kinodyn.ik import ccd
    from kinodyn.contact.avatar import build_avatar, pose_fk
    from kinodyn.data.skeleton import humanoid
    from kinodyn.math import quat

    av = build_avatar(humanoid())
    sk = av.skeleton
    chain = next(c for c in av.chains if sk.names[c[0]] == "LeftShoulder")
    lim = ccd.chain_limits(av.limits, av.cone_axes, av.cone_points, chain)
    gr, gp = pose_fk(sk, np.zeros(3), quat.identity((sk.num_joints,)))
    base = sk.parents[chain[0]]
    tip = sk.end_offsets[list(sk.end_parents).index(chain[-1])]
    rng = np.random.default_rng(0)
    n = 20 if quick else 100
    # goals the arm can reach: tips of random in-limit poses
    goals = []
    for _ in range(n):
        q = ccd.project_chain(quat.from_rotvec(rng.normal(0, 0.6, (len(chain), 3))), lim)
        r, p = ccd.chain_fk(gr[base], gp[base], sk.offsets[chain], q)
        goals.append(p[-1] + quat.mul_vec(r[-1], tip))
    q0 = np.tile([1.0, 0, 0, 0], (len(chain), 1))
    cfg = ccd.CCDConfig(tolerance=1e-4, max_sweeps=50)
    ccd.ccd_solve(gr[base], gp[base], sk.offsets[chain], q0, len(chain) - 1, tip, goals[0], lim, cfg)  # compiled
    t0 = time.thread_time()
    errs = [ccd.ccd_solve(gr[base], gp[base], sk.offsets[chain], q0, len(chain) - 1, tip, g, lim, cfg).error
            for g in goals]
    ours = (time.thread_time() - t0) / n
    res.add("ik_us_per_chain", ours * 1e6, "us")
    res.add("ik_error_mm", float(np.median(errs)) * 1e3, "mm")
    try:
        theirs, their_err = _ikpy(sk, chain, gp[base], tip, goals)
    except ImportError:
        res.notes["ikpy"] = "not installed"
        return
    res.add("ikpy_us_per_chain", theirs * 1e6, "us")
    res.add("ikpy_error_mm", their_err * 1e3, "mm")
    res.add("ik_speedup_vs_ikpy", theirs / ours, "x")
    res.baseline["ikpy_us_per_chain"] = theirs * 1e6


def _ikpy(sk, chain, base_pos, tip, goals):
    """ikpy on the same arm: each ball joint as three revolute axes, the elbow hinge, the same tip."""
    import warnings

    from ikpy.chain import Chain
    from ikpy.link import OriginLink, URDFLink

    links = [OriginLink()]
    axes = {"ball": ([1, 0, 0], [0, 1, 0], [0, 0, 1])}
    from kinodyn import limits as jl

    lims = jl.limits_for(sk)
    for j in chain:
        off = sk.offsets[j]
        ax = [list(lims[j].axis)] if lims[j].kind == "hinge" else list(axes["ball"])
        for k, a in enumerate(ax):
            links.append(URDFLink(f"{sk.names[j]}_{k}", origin_translation=off if k == 0 else [0, 0, 0],
                                  origin_orientation=[0, 0, 0], rotation=a))
    links.append(URDFLink("tip", origin_translation=tip, origin_orientation=[0, 0, 0], rotation=None,
                          joint_type="fixed"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        arm = Chain(links, active_links_mask=[False] + [True] * (len(links) - 2) + [False])
        t0 = time.thread_time()
        errs = []
        for g in goals:
            q = arm.inverse_kinematics(np.asarray(g) - base_pos)
            errs.append(np.linalg.norm(arm.forward_kinematics(q)[:3, 3] - (np.asarray(g) - base_pos)))
        return (time.thread_time() - t0) / len(goals), float(np.median(errs))


def run(quick: bool = False, progress=None) -> BenchResult:
    res = BenchResult("contact")
    _narrow(res, quick)
    _ik(res, quick)
    _scenarios(res, progress)
    res.notes["one_core"] = "numba pinned to 1 thread; MuJoCo queries single-threaded"
    return res
