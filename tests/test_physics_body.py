"""The MuJoCo body of a skeleton: segments, merging, masses, limits, the index map, MJCF export."""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from kinodyn.data import library
from kinodyn.data.skeleton import humanoid
from kinodyn.errors import KinodynError, MotionError, ParameterError, SkeletonError
from kinodyn.limits import limits_for
from kinodyn.physics import body as B
from kinodyn.physics.world import clip_qvel
from kinodyn.skeleton import Skeleton

_TOL = 1e-9


@pytest.fixture(scope="module")
def hbody():
    return B.build_body(humanoid())


def _fk_check(body, motion, frames):
    """MuJoCo's forward kinematics of the qpos we write must put every segment where kinodyn's FK of the
    motion read back from that qpos puts its joint."""
    m = body.compile()
    d = mujoco.MjData(m)
    q = B.motion_to_qpos(body.map, motion.root_pos[frames], motion.local_rot[frames])
    back = B.qpos_to_local_rot(body.map, q)
    from kinodyn.kinematics import fk_arrays

    _, gp = fk_arrays(motion.root_pos[frames], back, motion.skeleton.offsets, motion.skeleton.parents)
    for k in range(len(frames)):
        d.qpos[:] = q[k]
        mujoco.mj_kinematics(m, d)
        np.testing.assert_allclose(d.xpos[1:], gp[k, body.map.body_joint], atol=1e-9)


def test_humanoid_body_is_complete(hbody):
    bm = hbody.map
    sk = humanoid()
    assert bm.num_bodies == sk.num_joints  # nothing merged in the built-in humanoid (toes are boxes)
    assert abs(hbody.total_mass - 70.0) < 1e-6
    m = hbody.compile()
    assert m.nq == bm.nq and m.nv == bm.nv and m.nu == bm.nu
    assert m.nbody == bm.num_bodies + 1
    masses = m.body_mass[1:]
    assert np.all(masses > 0)
    # the trunk is the heaviest part, a thigh outweighs a shin, a shin a foot
    names = list(bm.names)
    assert masses[names.index("Spine1")] > masses[names.index("LeftUpLeg")] > masses[names.index("LeftLeg")] \
        > masses[names.index("LeftFoot")]
    # left/right symmetric masses
    assert masses[names.index("LeftArm")] == pytest.approx(masses[names.index("RightArm")])
    # feet are boxes, limbs capsules
    gid = m.geom("LeftFoot").id
    assert m.geom_type[gid] == mujoco.mjtGeom.mjGEOM_BOX
    assert m.geom_type[m.geom("LeftArm").id] == mujoco.mjtGeom.mjGEOM_CAPSULE
    assert bm.feet == {"left": names.index("LeftFoot"), "right": names.index("RightFoot")}


def test_joint_limits_come_from_kinodyn_limits(hbody):
    m = hbody.compile()
    lims = limits_for(humanoid())
    for b, s in enumerate(hbody.map.segments):
        lim = lims[s.joint]
        if s.kind == "free":
            assert lim.kind == "root"
            continue
        jid = m.joint(s.name).id
        if lim.kind == "hinge":
            assert m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_HINGE
            np.testing.assert_allclose(m.jnt_axis[jid], lim.axis, atol=1e-12)
            np.testing.assert_allclose(m.jnt_range[jid], [lim.lower, lim.upper], atol=1e-12)
        else:
            assert m.jnt_type[jid] == mujoco.mjtJoint.mjJNT_BALL
            assert m.jnt_range[jid][1] == pytest.approx(lim.max_angle)
            assert bool(m.jnt_limited[jid]) == (lim.max_angle < np.pi - 1e-6)


def test_no_collision_between_adjacent_segments(hbody):
    m = hbody.compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert not (m.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_FILTERPARENT)  # parent/child pairs filtered
    for i in range(d.ncon):  # the rest pose touches only the ground
        g1, g2 = d.contact.geom1[i], d.contact.geom2[i]
        assert 0 in (m.geom_bodyid[g1], m.geom_bodyid[g2])


def test_map_round_trip_against_mujoco_fk(hbody):
    walk = library.load("walk")
    _fk_check(hbody, walk, np.arange(0, walk.num_frames, 7))


def test_qvel_matches_mj_differentiatePos(hbody):
    walk = library.load("walk")
    m = hbody.compile()
    v = clip_qvel(hbody.map, walk.root_pos, walk.local_rot, walk.fps)
    q = B.motion_to_qpos(hbody.map, walk.root_pos, walk.local_rot)
    ref = np.zeros(m.nv)
    for f in (1, 30, 77):
        mujoco.mj_differentiatePos(m, ref, 2.0 / walk.fps, q[f - 1], q[f + 1])
        np.testing.assert_allclose(v[f], ref, atol=1e-9, err_msg=f"frame {f}")


def test_ctrl_targets_are_the_body_rotations(hbody):
    walk = library.load("walk")
    ctrl = B.pose_to_ctrl(hbody.map, walk.local_rot[10])
    q = B.motion_to_qpos(hbody.map, walk.root_pos[10], walk.local_rot[10])
    for b in hbody.map.actuated:
        a, w = hbody.map.ctrl_adr[b], hbody.map.ctrl_width[b]
        qa = hbody.map.qpos_adr[b]
        np.testing.assert_allclose(ctrl[a:a + w], q[qa:qa + w], atol=_TOL)


def test_mjcf_export_compiles(hbody, tmp_path):
    xml = hbody.to_xml()
    m = mujoco.MjModel.from_xml_string(xml)
    assert m.nbody == hbody.map.num_bodies + 1  # world + segments
    assert m.nu == hbody.map.nu
    assert m.ngeom >= hbody.map.num_bodies + 1  # ground plane included
    d = mujoco.MjData(m)
    for _ in range(50):
        mujoco.mj_step(m, d)
    assert np.isfinite(d.qpos).all()


def test_body_command_writes_mjcf(tmp_path, capsys):
    from kinodyn.cli import main

    out = tmp_path / "body.xml"
    assert main(["body", "humanoid", "-o", str(out)]) == 0
    m = mujoco.MjModel.from_xml_path(str(out))
    assert m.nbody == humanoid().num_joints + 1
    assert "wrote" in capsys.readouterr().out
    # a BVH file works too
    from kinodyn.io import save

    bvh = tmp_path / "walk.bvh"
    save(bvh, library.load("walk"))
    out2 = tmp_path / "b2.xml"
    assert main(["body", str(bvh), "-o", str(out2), "--mass", "80"]) == 0
    assert mujoco.MjModel.from_xml_path(str(out2)).body_mass.sum() == pytest.approx(80.0)


def test_body_command_bad_input(tmp_path, capsys):
    from kinodyn.cli import main

    assert main(["body", "no_such_clip", "-o", str(tmp_path / "x.xml")]) == 2
    assert main(["body", "humanoid", "-o", str(tmp_path / "x.xml"), "--mass", "-5"]) == 2
    err = capsys.readouterr().err
    assert "mass must be a positive" in err
    assert not (tmp_path / "x.xml").exists()


def test_negative_mass_is_a_clear_error():
    with pytest.raises(ParameterError, match="mass must be a positive"):
        B.BodyConfig(mass=-1.0)
    with pytest.raises(ParameterError):
        B.BodyConfig(mass=float("nan"))
    with pytest.raises(KinodynError):
        B.build_body(humanoid(), B.BodyConfig(mass=0.0))


def _chain(offsets, names=None):
    n = len(offsets)
    names = names or [f"j{i}" for i in range(n)]
    return Skeleton(names, np.array([-1] + list(range(n - 1))), np.array(offsets, dtype=float))


def test_zero_length_bone_is_a_clear_error():
    sk = humanoid()
    off = np.array(sk.offsets)
    off[sk.index("LeftLeg")] = 0.0  # the knee at the hip
    bad = sk.replace(offsets=off)
    with pytest.raises(SkeletonError, match="zero-length bone") as e:
        B.build_body(bad)
    assert "LeftLeg" in str(e.value)
    with pytest.raises(SkeletonError, match="no extent"):
        B.build_body(_chain([[0, 0, 0], [0, 0, 0], [0, 0, 0]]))


def test_duplicate_joints_at_branches_are_merged():
    """CMU-style zero-length joints at a branch (hip joints, neck, clavicles) merge into their parent."""
    sk = humanoid()
    names = list(sk.names) + ["LHipJoint"]
    # insert a zero-offset 'LHipJoint' between Hips and LeftUpLeg
    parents = list(sk.parents) + [0]
    off = np.vstack([sk.offsets, np.zeros(3)])
    # reorder so parents come first: build a new skeleton with LHipJoint right after Hips
    order = [0, len(names) - 1] + list(range(1, len(names) - 1))
    inv = np.argsort(order)
    new_par = [-1] + [int(inv[parents[o]]) for o in order[1:]]
    new_par[inv[sk.index("LeftUpLeg")]] = 1
    sk2 = Skeleton([names[o] for o in order], np.array(new_par), off[order],
                   end_parents=inv[sk.end_parents], end_offsets=sk.end_offsets)
    body = B.build_body(sk2)
    assert "LHipJoint" in body.map.segments[0].merged
    assert body.map.num_bodies == sk.num_joints


def test_segment_table_and_landmarks(hbody):
    bm = hbody.map
    assert bm.segments[bm.landmark("chest")].name == "Spine1"
    assert bm.segments[bm.landmark("stomach")].name == "Spine"
    assert bm.segments[bm.landmark("pelvis")].name == "Hips"
    assert bm.segments[bm.landmark("left_hand")].name == "LeftHand"
    assert bm.segments[bm.body("LeftToeBase")].cls == "toe"
    assert [bm.segments[b].name for b in bm.spine_bodies()] == ["Hips", "Spine", "Spine1", "Neck", "Head"]
    from kinodyn.errors import UnknownNameError

    with pytest.raises(UnknownNameError, match="landmarks"):
        bm.landmark("tail")


def test_other_skeleton_is_rejected(hbody):
    other = _chain([[0, 0, 0], [0, 0, 0.3], [0, 0, 0.3]])
    with pytest.raises(MotionError, match="another skeleton"):
        B.check_skeleton(hbody.map, other)


@pytest.mark.mocap
def test_cmu_skeleton_builds(mocap_dir):
    from kinodyn.io import load

    path = mocap_dir / "locomotion" / "cmu_01_01.bvh"
    if not path.exists():
        pytest.skip("cmu_01_01.bvh not in the shared mocap folder")
    motion = load(path)[1:]
    sk = motion.skeleton
    assert sk.num_joints == 31
    body = B.build_body(sk)
    merged = {n for s in body.map.segments for n in s.merged}
    # the duplicated hip and neck joints and the fingers are merged into their parents
    assert {"LHipJoint", "RHipJoint", "Neck", "LFingers", "LThumb", "RFingers", "RThumb"} <= merged
    assert 15 <= body.map.num_bodies <= 21
    assert abs(body.total_mass - 70.0) < 1e-6
    m = mujoco.MjModel.from_xml_string(body.to_xml())
    assert m.nbody == body.map.num_bodies + 1
    # classes found from the tree
    classes = {s.name: s.cls for s in body.map.segments}
    assert classes["Hips"] == "pelvis" and classes["Spine1"] == "chest" and classes["Head"] == "head"
    assert classes["LeftFoot"] == "foot" and classes["LeftLeg"] == "shin"
    # a simulated CMU body: its clip played kinematically reads back exactly (merged joints aside)
    from kinodyn.physics.world import World

    w = World()
    c = w.add_character(body)
    c.play(motion[:240], align_floor=False)
    w.run(1.0)
    sim = c.trajectory()
    ref = motion.resample(60.0)[: sim.num_frames]
    kept = [j for j in body.map.body_joint if "Hand" not in sk.names[j]]
    err = np.linalg.norm(sim.global_positions()[:, kept] - ref.global_positions()[:, kept], axis=-1)
    # the merged LowerBack and Neck are rigid (their rotations fold into Spine and Neck1), so the upper
    # body moves a little; the legs are exact to 0.1 mm. (Hands move more: elbows are hinges and CMU's forearms
    # also twist and swing off the hinge axis.)
    legs = [k for k, j in enumerate(kept) if "Leg" in sk.names[j] or "Foot" in sk.names[j]]
    assert err[:, legs].max() < 1e-4  # knees are hinges: CMU knees bend about one axis
    assert err.max() < 0.04
