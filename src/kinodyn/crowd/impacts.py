"""The impact experiment of section 6 and an automatic observer in place of the human subjects.

Mitake et al., section 6.2, figure 9 and table 1. A standing character is hit once by a force ``F``
applied at height ``h`` on its surface at the angle ``theta_pos`` around its vertical axis (0: the
front), pointing at the angle ``theta_dir`` away from the inward horizontal direction; ``theta_pos``
and ``theta_dir`` range over -45, 0 and 45 degrees, ``h`` over 0, 0.5 and 1.0 m, and ``|F|`` is strong
or weak: 54 reactions. The paper asked six people to watch each reaction and choose the force; here
an *observer* does it: a classifier per parameter trained on reactions generated with other random
seeds (other starting phases, small variations of strength, height and timing), which sees only the
posed motion (joint positions in the character's starting frame). Accuracy is the share of exact
answers; the errors are in steps of the choices (the paper's normalization), with the direction
scored as ``theta_dir + theta_pos`` as in the paper. Table 1 (human subjects): accuracy 0.73, 0.78,
0.54, 0.88 for theta_pos, theta_dir + theta_pos, h, |F|.

Angles in radians inside, degrees in the labels; metres; newton seconds.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from kinodyn.crowd.body import BodyConfig
from kinodyn.crowd.crowd import Crowd, CrowdConfig
from kinodyn.errors import ParameterError

__all__ = [
    "ANGLES",
    "HEIGHTS",
    "PAPER_ACCURACY",
    "STRENGTHS",
    "ImpactConfig",
    "ImpactSet",
    "Observer",
    "evaluate_observer",
    "experiment",
    "features",
    "force_geometry",
    "run_impacts",
]

ANGLES = (-45.0, 0.0, 45.0)
HEIGHTS = (0.0, 0.5, 1.0)
STRENGTHS = ("weak", "strong")
#: Table 1: theta_pos, theta_dir + theta_pos, h, |F|.
PAPER_ACCURACY = {"pos": 0.73, "dir": 0.78, "height": 0.54, "strength": 0.88}
PAPER_MU = {"pos": 0.017, "dir": -0.099, "height": -0.008, "strength": 0.041}
PAPER_SIGMA = {"pos": 0.545, "dir": 0.488, "height": 0.766, "strength": 0.350}


@dataclass(frozen=True)
class ImpactConfig:
    """The forces and the recording of the experiment.

    Attributes:
        weak, strong: impulses in newton seconds, applied over ``duration`` seconds.
        duration: seconds the force lasts.
        settle: seconds standing before the hit.
        seconds: seconds recorded after the hit.
        spacing: metres between the characters (one crowd holds all reactions, far apart).
        jitter: relative spread of strength and timing between seeds (heights get 3 cm).
    """

    weak: float = 40.0
    strong: float = 140.0
    duration: float = 0.1
    settle: float = 0.5
    seconds: float = 4.0
    spacing: float = 8.0
    jitter: float = 0.1

    def __post_init__(self):
        if not (0 < self.weak < self.strong):
            raise ParameterError(f"ImpactConfig needs 0 < weak < strong, got {self.weak} and {self.strong}")


@dataclass(frozen=True)
class ImpactSet:
    """Reactions and their force parameters.

    Attributes:
        labels: ``(R, 4)`` ints: indices into ANGLES (pos), ANGLES (dir), HEIGHTS, STRENGTHS.
        root_pos: ``(R, F, 3)`` and local_rot ``(R, F, J, 4)``: the posed motion from the hit on.
        modes: ``(R, F)`` controller states.
        fps: frames per second.
    """

    labels: np.ndarray
    root_pos: np.ndarray
    local_rot: np.ndarray
    modes: np.ndarray
    fps: float


def experiment() -> np.ndarray:
    """``(54, 4)`` label indices of every combination, in a fixed order."""
    return np.array(list(product(range(3), range(3), range(3), range(2))), dtype=np.int64)


def force_geometry(body: BodyConfig, theta_pos, theta_dir, height) -> tuple[np.ndarray, np.ndarray]:
    """Application point (in the body frame Sr, relative to the centre of mass) and unit direction
    (in Sr) of forces of figure 9, for an upright body.

    Args:
        theta_pos, theta_dir: ``(R,)`` radians.
        height: ``(R,)`` metres above the floor.

    Returns:
        ``(point (R, 3), direction (R, 3))``.
    """
    a = body.semi_axes
    zc = np.clip(np.asarray(height, float) - 0.5 * body.height, -a[2], a[2])
    ring = np.sqrt(np.maximum(0.0, 1.0 - (zc / a[2]) ** 2))
    c, s = np.cos(theta_pos), np.sin(theta_pos)
    # the ellipse's radius along the azimuth theta_pos
    rad = ring / np.sqrt((c / a[0]) ** 2 + (s / a[1]) ** 2)
    point = np.stack([rad * c, rad * s, zc + body.shape_offset[2]], axis=-1)
    ang = np.asarray(theta_pos) + np.asarray(theta_dir) + np.pi
    direction = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], axis=-1)
    return point, direction


def run_impacts(labels: np.ndarray, seed: int, cfg: ImpactConfig | None = None,
                body: BodyConfig | None = None, keyframes=None) -> ImpactSet:
    """Simulate one reaction per row of ``labels (R, 4)``, all in one crowd, seeded.

    The seed sets the starting walk phases, the headings and the small variations of strength,
    height and timing (``cfg.jitter``).
    """
    from kinodyn.math import quat

    cfg, body = cfg or ImpactConfig(), body or BodyConfig()
    labels = np.asarray(labels, np.int64)
    r = len(labels)
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(r)))
    pos = cfg.spacing * np.stack([np.arange(r) % side, np.arange(r) // side], axis=1).astype(float)
    heading = rng.uniform(-np.pi, np.pi, r)
    crowd = Crowd(pos, heading, body=body, keyframes=keyframes, config=CrowdConfig(balls=0), seed=seed)
    fps = crowd.config.fps
    start = np.round((cfg.settle + rng.uniform(0, cfg.jitter, r)) * fps).astype(int)
    impulse = np.where(labels[:, 3] == 1, cfg.strong, cfg.weak) * rng.uniform(1 - cfg.jitter, 1 + cfg.jitter, r)
    h = np.asarray(HEIGHTS)[labels[:, 2]] + rng.uniform(-0.03, 0.03, r)
    point, direction = force_geometry(body, np.radians(np.asarray(ANGLES)[labels[:, 0]]),
                                      np.radians(np.asarray(ANGLES)[labels[:, 1]]), np.maximum(h, 0.0))
    frames = round(cfg.seconds * fps)
    crowd.start_recording()
    for f in range(int(start.max()) + frames):
        hit = np.flatnonzero(start == f)
        if len(hit):
            q = crowd.state.quat[hit]
            crowd.push(hit, quat.mul_vec(q, direction[hit]) * (impulse[hit] / cfg.duration)[:, None],
                       point=crowd.state.r[hit] + quat.mul_vec(q, point[hit]), duration=cfg.duration)
        crowd.step()
    rec = crowd.recording()
    idx = start[:, None] + np.arange(frames)[None, :]
    who = np.arange(r)[:, None]
    return ImpactSet(labels=labels, root_pos=rec["root_pos"][idx, who], local_rot=rec["local_rot"][idx, who],
                     modes=rec["mode"][idx, who], fps=fps)


def _joint_positions(ks_skeleton, root_pos, local_rot) -> np.ndarray:
    from kinodyn.math import quat

    lp = np.broadcast_to(np.asarray(ks_skeleton.offsets), local_rot.shape[:-1] + (3,)).copy()
    lp[..., 0, :] = root_pos
    return quat.fk(local_rot.astype(np.float64), lp, ks_skeleton.parents)[1]


def features(imp: ImpactSet, skeleton, samples: int = 16) -> np.ndarray:
    """``(R, D)`` features of the posed reactions: joint positions at ``samples`` times, in each
    character's frame at the moment of the hit (its root position and heading), plus their largest
    displacement and height drop. Only the posed motion is used."""
    from kinodyn.math import quat

    r, f = imp.root_pos.shape[:2]
    t = np.linspace(0, f - 1, samples).round().astype(int)
    pos = _joint_positions(skeleton, imp.root_pos[:, t], imp.local_rot[:, t])  # (R, T, J, 3)
    hips0 = pos[:, 0, 0]
    facing = quat.heading(imp.local_rot[:, 0, 0].astype(np.float64), forward=[1.0, 0.0, 0.0])
    inv = quat.from_heading(-facing)[:, None, None, :]
    rel = quat.mul_vec(inv, pos - hips0[:, None, None, :] * np.array([1.0, 1.0, 0.0]))
    keep = [skeleton.index(n) for n in ("Hips", "Head", "LeftHand", "RightHand", "LeftFoot", "RightFoot")]
    sel = rel[:, :, keep]  # (R, T, 6, 3)
    path = sel[:, :, 0, :2]
    extra = np.concatenate([np.abs(path).max(axis=1), [[np.min(sel[i, :, 1, 2])] for i in range(r)]], axis=1)
    return np.concatenate([sel.reshape(r, -1), extra], axis=1)


def _targets(labels: np.ndarray) -> dict[str, np.ndarray]:
    """Per parameter the class index: pos (0..2), dir = theta_dir + theta_pos (0..4), height, strength."""
    return {"pos": labels[:, 0], "dir": labels[:, 0] + labels[:, 1], "height": labels[:, 2],
            "strength": labels[:, 3]}


class Observer:
    """One classifier per force parameter (scikit-learn, a standardized RBF support vector machine)."""

    def __init__(self):
        self.models: dict = {}

    def fit(self, x: np.ndarray, labels: np.ndarray) -> Observer:
        from sklearn.pipeline import make_pipeline
        from sklearn.preprocessing import StandardScaler
        from sklearn.svm import SVC

        for k, y in _targets(labels).items():
            self.models[k] = make_pipeline(StandardScaler(), SVC(C=10.0, gamma="scale")).fit(x, y)
        return self

    def predict(self, x: np.ndarray) -> dict[str, np.ndarray]:
        return {k: m.predict(x) for k, m in self.models.items()}


def evaluate_observer(train: list[ImpactSet], test: list[ImpactSet], skeleton) -> dict[str, dict[str, float]]:
    """Train on ``train`` reactions, score on ``test`` (other seeds): per parameter ``accuracy``,
    ``mu`` and ``sigma`` of the signed error in steps of the choices (table 1)."""
    xtr = np.concatenate([features(s, skeleton) for s in train])
    ytr = np.concatenate([s.labels for s in train])
    xte = np.concatenate([features(s, skeleton) for s in test])
    yte = np.concatenate([s.labels for s in test])
    pred = Observer().fit(xtr, ytr).predict(xte)
    truth = _targets(yte)
    out = {}
    for k in truth:
        err = (pred[k] - truth[k]).astype(float)
        out[k] = {"accuracy": float(np.mean(err == 0)), "mu": float(err.mean()), "sigma": float(err.std()),
                  "paper_accuracy": PAPER_ACCURACY[k], "paper_mu": PAPER_MU[k], "paper_sigma": PAPER_SIGMA[k]}
    return out
