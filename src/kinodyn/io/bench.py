"""I/O benchmark: BVH parse throughput, forward-kinematics throughput and AMC parse time.

``kinodyn bench io [--quick] --json FILE`` reports

* ``bvh_frames_per_s``: frames per second of :func:`kinodyn.io.bvh.read_bvh` (file to Z-up metre
  :class:`~kinodyn.motion.Motion`, unit detection included) on a 10,000-frame, 31-joint CMU-sized file;
* ``fk_joint_frames_per_s``: joint positions per second of :meth:`Motion.global_positions` on it;
* ``amc_parse_s``: seconds of :func:`kinodyn.io.amc.read_amc` (ASF and AMC) for CMU trial 01_01
  (2,751 frames);
* ``parse_fk_frames_per_s`` and speed-up ratios against the baselines;
* ``cold_info_s``, ``cold_info_mb``: wall-clock seconds and peak resident memory (MB) of a whole
  ``kinodyn info FILE`` process on a small CMU file (cmu_02_01, 344 frames; a synthetic file of that
  size without the mocap folder), bytecode and numba caches warm, as a user runs it the second time;
  ``cold_bvh_pypi_s`` the same for ``python -c "import bvh; ..."`` parsing that file, and
  ``cold_ratio_vs_bvh_pypi`` the ratio of the two (kinodyn's time over the ``bvh`` package's). Goal:
  ``cold_info_s`` under 0.3 s;
* ``library_generate_s``: seconds to generate every built-in clip (cache cleared), and
  ``bvh_huge_header_reject_s``: seconds to reject a 20 MB hierarchy without ``MOTION``.

The test file is CMU 01_01 (cgspeed BVH) with its frames tiled to 10,000 when ``../shared/mocap`` is
present (or ``KINODYN_MOCAP`` names the folder); otherwise a synthetic CMU-shaped ASF/AMC pair (the CMU
subject-01 skeleton, smooth random dof curves) is generated and written as BVH with CMU's units and
4 decimals, so the file has the same size per frame as the real one. Times are medians of repeats after
a warm-up (numba kernels compiled or loaded from the cache first).

Baselines: the ``bvh`` package from PyPI (the fastest pure BVH reader there) is timed on the same file
in the same run when installed. fairmotion and bvhio cannot be installed here cheaply (fairmotion pins
torch 1.4), so their parse + FK figures on cmu_01_01 (2,752 frames) measured on this machine kind are
used as reference values (``*_ref``). Goals from the foundation issue: parsing 10x the ``bvh``
package, parse + FK 50x fairmotion and bvhio.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from kinodyn.bench import BenchResult
from kinodyn.io import mocapdir

__all__ = [
    "BENCH_FRAMES",
    "COLD_FRAMES",
    "cold_start",
    "find_mocap",
    "make_amc_files",
    "make_bvh_file",
    "run",
    "synthetic_amc_text",
    "synthetic_asf_text",
]

#: Frames of the BVH benchmark file.
BENCH_FRAMES = 10_000
#: Reference figures measured on this machine kind (../shared/notes/measured-here.md) on cmu_01_01.bvh,
#: 2,752 frames: parse + forward kinematics seconds.
_REF_PARSE_FK_S = {"fairmotion": 3.5 + 0.74, "bvhio": 3.6 + 0.57}
_REF_FRAMES = 2752
_GOAL_PARSE_SPEEDUP = 10.0
_GOAL_PARSE_FK_SPEEDUP = 50.0
_GOAL_COLD_INFO_S = 0.3
#: frames of the small CMU file of the cold-start figures (cmu_02_01.bvh)
COLD_FRAMES = 344

# CMU subject 01's ASF bones: name, parent, direction, length (file units), axis (deg, XYZ), dofs.
_CMU_BONES = (
    ("lhipjoint", "root", (0.566809, -0.746272, 0.349008), 2.40479, (0, 0, 0), ""),
    ("lfemur", "lhipjoint", (0.34202, -0.939693, 0), 7.1578, (0, 0, 20), "rx ry rz"),
    ("ltibia", "lfemur", (0.34202, -0.939693, 0), 7.49137, (0, 0, 20), "rx"),
    ("lfoot", "ltibia", (0.0665746, -0.182912, 0.980873), 2.36784, (-90, 0, 20), "rx rz"),
    ("ltoes", "lfoot", (0, 0, 1), 1.18966, (-90, 0, 20), "rx"),
    ("rhipjoint", "root", (-0.550236, -0.756381, 0.353735), 2.37265, (0, 0, 0), ""),
    ("rfemur", "rhipjoint", (-0.34202, -0.939693, 0), 7.43386, (0, 0, -20), "rx ry rz"),
    ("rtibia", "rfemur", (-0.34202, -0.939693, 0), 7.50908, (0, 0, -20), "rx"),
    ("rfoot", "rtibia", (-0.0683029, -0.187661, 0.979856), 2.41173, (-90, 0, -20), "rx rz"),
    ("rtoes", "rfoot", (0, 0, 1), 1.21082, (-90, 0, -20), "rx"),
    ("lowerback", "root", (0.013823, 0.995423, -0.0945635), 2.04495, (0, 0, 0), "rx ry rz"),
    ("upperback", "lowerback", (0.0276657, 0.9994, -0.020853), 2.05008, (0, 0, 0), "rx ry rz"),
    ("thorax", "upperback", (0.019782, 0.999531, 0.0233827), 2.06488, (0, 0, 0), "rx ry rz"),
    ("lowerneck", "thorax", (-0.0308541, 0.994709, 0.0979874), 1.75553, (0, 0, 0), "rx ry rz"),
    ("upperneck", "lowerneck", (0.0588398, 0.995804, -0.0700903), 1.76878, (0, 0, 0), "rx ry rz"),
    ("head", "upperneck", (0.0209966, 0.999159, -0.0352225), 1.77193, (0, 0, 0), "rx ry rz"),
    ("lclavicle", "thorax", (0.938182, 0.335073, -0.0868338), 3.58396, (0, 0, 0), "ry rz"),
    ("lhumerus", "lclavicle", (1, 0, 0), 4.983, (180, -30, -90), "rx ry rz"),
    ("lradius", "lhumerus", (1, 0, 0), 3.48356, (180, -30, -90), "rx"),
    ("lwrist", "lradius", (1, 0, 0), 1.74178, (0, 90, 90), "ry"),
    ("lhand", "lwrist", (1, 0, 0), 0.715259, (0, 90, 90), "rx rz"),
    ("lfingers", "lhand", (1, 0, 0), 0.576661, (0, 90, 90), "rx"),
    ("lthumb", "lwrist", (0.707107, 0, 0.707107), 0.827973, (-90, 45, 0), "rx rz"),
    ("rclavicle", "thorax", (-0.909637, 0.398485, -0.11735), 3.44819, (0, 0, 0), "ry rz"),
    ("rhumerus", "rclavicle", (-1, 0, 0), 5.2419, (180, 30, 90), "rx ry rz"),
    ("rradius", "rhumerus", (-1, 0, 0), 3.44417, (180, 30, 90), "rx"),
    ("rwrist", "rradius", (-1, 0, 0), 1.72209, (0, -90, -90), "ry"),
    ("rhand", "rwrist", (-1, 0, 0), 0.622529, (0, -90, -90), "rx rz"),
    ("rfingers", "rhand", (-1, 0, 0), 0.501899, (0, -90, -90), "rx"),
    ("rthumb", "rwrist", (-0.707107, 0, 0.707107), 0.720629, (-90, -45, 0), "rx rz"),
)


def find_mocap() -> Path | None:
    """The shared motion-capture folder (:func:`kinodyn.io.mocapdir.find`)."""
    return mocapdir.find()


def synthetic_asf_text() -> str:
    """An ASF file with CMU subject 01's skeleton (31 segments, 62 dofs, ``length 0.45``)."""
    out = [":version 1.10", ":name VICON", ":units", "  mass 1.0", "  length 0.45", "  angle deg", ":root",
           "   order TX TY TZ RX RY RZ", "   axis XYZ", "   position 0 0 0", "   orientation 0 0 0", ":bonedata"]
    for k, (name, _parent, d, length, ax, dof) in enumerate(_CMU_BONES, start=1):
        out += ["  begin", f"     id {k}", f"     name {name}", f"     direction {d[0]:g} {d[1]:g} {d[2]:g}",
                f"     length {length:g}", f"     axis {ax[0]:g} {ax[1]:g} {ax[2]:g} XYZ"]
        if dof:
            out.append(f"    dof {dof}")
            out.append("    limits " + "\n           ".join("(-180.0 180.0)" for _ in dof.split()))
        out.append("  end")
    out += [":hierarchy", "  begin"]
    children: dict[str, list[str]] = {}
    for name, parent, *_ in _CMU_BONES:
        children.setdefault(parent, []).append(name)
    for parent in ["root"] + [b[0] for b in _CMU_BONES]:
        if parent in children:
            out.append(f"    {parent} {' '.join(children[parent])}")
    out += ["  end", ""]
    return "\n".join(out)


def synthetic_amc_text(frames: int = 2751, seed: int = 0) -> str:
    """An AMC file for :func:`synthetic_asf_text`: smooth random dof curves at 120 Hz (a jog-like root
    path), values written with 6 significant digits like CMU's files."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames) / 120.0
    bones = [("root", "tx ty tz rx ry rz")] + [(b[0], b[5]) for b in _CMU_BONES if b[5]]
    lines = ["#!OML:ASF synthetic.asf", ":FULLY-SPECIFIED", ":DEGREES"]
    cols = []
    for name, dof in bones:
        n = len(dof.split())
        amp = rng.uniform(2, 25, n)
        freq = rng.uniform(0.3, 2.0, n)
        phase = rng.uniform(0, 2 * np.pi, n)
        v = amp * np.sin(2 * np.pi * freq * t[:, None] + phase) + rng.normal(0, 0.05, (frames, n))
        if name == "root":
            v[:, 0] = 20.0 * np.sin(0.2 * t)
            v[:, 1] = 17.5 + 0.5 * np.sin(2 * np.pi * 1.5 * t)
            v[:, 2] = 20.0 * np.cos(0.2 * t)
        cols.append((name, v))
    for f in range(frames):
        lines.append(str(f + 1))
        for name, v in cols:
            lines.append(name + " " + " ".join(f"{x:.6g}" for x in v[f]))
    return "\n".join(lines) + "\n"


def make_amc_files(folder: Path, frames: int = 2751) -> tuple[Path, Path, str]:
    """``(amc, asf, source)``: CMU 01_01 from the mocap folder, else a synthetic pair written to ``folder``."""
    mocap = find_mocap()
    if mocap is not None:
        amc = mocap / "locomotion" / "cmu_01_01.amc"
        asf = mocap / "locomotion" / "cmu_01.asf"
        if amc.is_file() and asf.is_file():
            return amc, asf, f"CMU 01_01 ({amc})"
    folder = Path(folder)
    asf = folder / "synthetic_01.asf"
    amc = folder / "synthetic_01_01.amc"
    asf.write_text(synthetic_asf_text())
    amc.write_text(synthetic_amc_text(frames))
    return amc, asf, f"synthetic CMU-shaped ASF/AMC, {frames} frames"


def make_bvh_file(folder: Path, frames: int = BENCH_FRAMES) -> tuple[Path, str]:
    """A ``frames``-frame, 31-joint CMU-sized BVH in ``folder`` and a description of its source."""
    folder = Path(folder)
    out = folder / f"bench_{frames}.bvh"
    mocap = find_mocap()
    src = None if mocap is None else mocap / "locomotion" / "cmu_01_01.bvh"
    if src is not None and src.is_file():
        data = src.read_bytes()
        i = data.index(b"\nMOTION") + 1
        rows = [r for r in data[i:].replace(b"\r", b"").split(b"\n")[3:] if r.strip()]
        tiled = (rows * (frames // len(rows) + 1))[:frames]
        out.write_bytes(data[:i] + b"MOTION\nFrames: %d\nFrame Time: .0083333\n" % frames + b"\n".join(tiled)
                        + b"\n")
        return out, f"CMU 01_01 cgspeed BVH ({src.name}) tiled to {frames} frames"
    from kinodyn.io.amc import read_amc
    from kinodyn.io.bvh import write_bvh

    amc, asf, _ = make_amc_files(folder)
    m = read_amc(amc, asf=asf)
    reps = frames // m.num_frames + 1
    tiled = m.replace(root_pos=np.tile(m.root_pos, (reps, 1))[:frames],
                      local_rot=np.tile(m.local_rot, (reps, 1, 1))[:frames])
    write_bvh(out, tiled, scale="cmu", precision=4)
    return out, f"synthetic CMU-shaped motion (31 joints) written as BVH, {frames} frames"


def _median_time(fn, repeats: int) -> tuple[float, float]:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts), min(ts)


# Runs argv[1:] once and prints its wall seconds, peak resident KiB and CPU seconds. A small process of
# its own starts the measured one: Linux counts the memory a child shares with its parent before exec
# in the child's peak, so a child of the (large) benchmark process would report the benchmark's size.
_LAUNCHER = """import os, sys, time
t0 = time.perf_counter()
pid = os.posix_spawn(sys.argv[1], sys.argv[1:], os.environ, file_actions=[(os.POSIX_SPAWN_OPEN, 1, os.devnull,
                     os.O_WRONLY, 0)])
_, status, ru = os.wait4(pid, 0)
wall = time.perf_counter() - t0
sys.exit(f"exit {os.waitstatus_to_exitcode(status)}") if status else print(wall, ru.ru_maxrss, ru.ru_utime + ru.ru_stime)
"""


def _timed_process(cmd: list[str], env: dict) -> tuple[float, float, float]:
    """``(wall seconds, peak resident MB, CPU seconds)`` of one process running ``cmd``."""
    r = subprocess.run([sys.executable, "-c", _LAUNCHER, *cmd], env=env, capture_output=True, text=True,
                       timeout=600, check=False)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed: {r.stderr.strip()[-300:]}")
    wall, kib, cpu = r.stdout.split()
    return float(wall), float(kib) * 1024 / 1e6, float(cpu)  # Linux reports KiB


def cold_start(folder: Path, repeats: int = 9) -> dict:
    """Whole-process ``kinodyn info`` on a small CMU file against ``python -c "import bvh; ..."`` on it.

    Each command runs once untimed (bytecode and numba caches written, file cached), then ``repeats``
    times alternating; returns medians and bests of wall time and the peak resident memory.
    """
    mocap = find_mocap()
    path = None if mocap is None else mocap / "locomotion" / "cmu_02_01.bvh"
    if path is not None and path.is_file():
        src = f"CMU 02_01 cgspeed BVH ({path.name}, {COLD_FRAMES} frames)"
    else:
        path, src = make_bvh_file(Path(folder), frames=COLD_FRAMES)
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)  # a user's install has its bytecode cache
    pkg_root = str(Path(__file__).resolve().parents[2])  # this kinodyn, whether installed or not
    env["PYTHONPATH"] = os.pathsep.join([pkg_root] + [p for p in [env.get("PYTHONPATH")] if p])
    cmds = {"info": [sys.executable, "-m", "kinodyn.cli", "info", str(path)]}
    try:
        import bvh  # noqa: F401 - the PyPI `bvh` package (dev extra)
    except ImportError:
        pass
    else:
        cmds["bvh_pypi"] = [sys.executable, "-c", "import sys, bvh; bvh.Bvh(open(sys.argv[1]).read()).nframes",
                            str(path)]
    runs = {k: [] for k in cmds}
    for k, cmd in cmds.items():
        _timed_process(cmd, env)
    launcher = _timed_process([sys.executable, "-c", "pass"], env)
    for _ in range(repeats):
        for k, cmd in cmds.items():
            runs[k].append(_timed_process(cmd, env))
    out = {"file": src, "launcher_mb": launcher[1], "load": os.getloadavg()[0]}
    for k, rs in runs.items():
        walls = [r[0] for r in rs]
        out[k] = {"s": statistics.median(walls), "best_s": min(walls), "mb": max(r[1] for r in rs),
                  "cpu_s": statistics.median(r[2] for r in rs)}
    return out


_GENERATE_ALL = ("import time\nfrom kinodyn.data import library\nt0 = time.perf_counter()\n"
                 "for name in library.names():\n    library.load(name)\nprint(time.perf_counter() - t0)")


def _unit_speeds(tmp: Path) -> dict:
    """Seconds of two checks that used to be timed in unit tests: generating every built-in clip (in a
    fresh process, so nothing is cached) and rejecting a 20 MB BVH hierarchy without MOTION."""
    from kinodyn.errors import BVHParseError
    from kinodyn.io.bvh import read_bvh

    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).resolve().parents[2])]
                                        + [p for p in [env.get("PYTHONPATH")] if p])
    out = subprocess.run([sys.executable, "-c", _GENERATE_ALL], env=env, capture_output=True, text=True,
                         check=True, timeout=600).stdout
    huge = tmp / "huge.bvh"
    huge.write_bytes(b"HIERARCHY\n" + b"JOINT x { OFFSET 0 0 0 }\n" * 800_000)
    t0 = time.perf_counter()
    try:
        read_bvh(huge)
    except BVHParseError:
        pass
    return {"library_generate_s": float(out.split()[-1]), "bvh_huge_header_reject_s": time.perf_counter() - t0}


def run(quick: bool = False, progress=None) -> BenchResult:
    """Run the I/O benchmark (``quick``: fewer repeats, well under a minute)."""
    from kinodyn.io.amc import read_amc, read_asf
    from kinodyn.io.bvh import read_bvh

    reps_parse = 3 if quick else 9
    reps_fk = 5 if quick else 25
    reps_amc = 3 if quick else 9
    steps = ["make files", "warm up", "parse BVH", "forward kinematics", "parse AMC", "baseline: bvh package",
             "cold start", "library and huge header"]
    bar = progress(total=len(steps), desc="bench io") if progress is not None else None

    def step():
        if bar is not None:
            bar.update(1)

    res = BenchResult("io")
    with tempfile.TemporaryDirectory(prefix="kinodyn-bench-io-") as tmp:
        tmp = Path(tmp)
        bvh_path, bvh_src = make_bvh_file(tmp)
        amc_path, asf_path, amc_src = make_amc_files(tmp)
        step()
        motion = read_bvh(bvh_path)  # warm up: numba kernels, imports, file cache
        motion.global_positions()
        read_amc(amc_path, asf=asf_path)
        step()
        f, j = motion.num_frames, motion.num_joints
        t_parse, t_parse_best = _median_time(lambda: read_bvh(bvh_path), reps_parse)
        step()
        t_fk, t_fk_best = _median_time(motion.global_positions, reps_fk)
        step()
        t_amc, t_amc_best = _median_time(lambda: read_amc(amc_path, asf=read_asf(asf_path)), reps_amc)
        amc_frames = read_amc(amc_path, asf=asf_path).num_frames
        step()
        base_fps = None
        try:
            import bvh as bvh_pkg  # the PyPI `bvh` package (dev extra)
        except ImportError:
            res.notes["bvh_pypi"] = "the `bvh` package is not installed; no same-run baseline"
        else:
            t_pkg, _ = _median_time(lambda: bvh_pkg.Bvh(bvh_path.read_text()).nframes, 1 if quick else 3)
            base_fps = f / t_pkg
        step()
        _add_process_figures(res, tmp, quick, step)
    if bar is not None:
        bar.close()

    bvh_fps = f / t_parse
    res.add("bvh_frames_per_s", bvh_fps, "frames/s")
    res.add("fk_joint_frames_per_s", f * j / t_fk, "joint-frames/s")
    res.add("amc_parse_s", t_amc, "s")
    res.add("bvh_parse_s", t_parse, "s")
    res.add("fk_s", t_fk, "s")
    parse_fk_fps = f / (t_parse + t_fk)
    res.add("parse_fk_frames_per_s", parse_fk_fps, "frames/s")
    res.add("amc_frames_per_s", amc_frames / t_amc, "frames/s")
    if base_fps is not None:
        res.baseline["bvh_pypi_frames_per_s"] = base_fps
        res.add("speedup_vs_bvh_pypi", bvh_fps / base_fps, "x")
    for name, secs in _REF_PARSE_FK_S.items():
        ref = _REF_FRAMES / secs
        res.baseline[f"{name}_parse_fk_frames_per_s_ref"] = ref
        res.add(f"speedup_parse_fk_vs_{name}_ref", parse_fk_fps / ref, "x")
    res.baseline["goal_speedup_parse_vs_bvh_pypi"] = _GOAL_PARSE_SPEEDUP
    res.baseline["goal_speedup_parse_fk_vs_fairmotion_bvhio"] = _GOAL_PARSE_FK_SPEEDUP
    res.notes.update({
        "bvh_file": f"{bvh_src}; {f} frames x {j} joints",
        "amc_file": f"{amc_src}; {amc_frames} frames",
        "timing": f"median of {reps_parse} (BVH), {reps_fk} (FK), {reps_amc} (AMC) runs after a warm-up; "
                  f"best BVH {t_parse_best * 1e3:.1f} ms, best FK {t_fk_best * 1e3:.2f} ms, best AMC "
                  f"{t_amc_best * 1e3:.1f} ms",
        "bvh_frames_per_s": "read_bvh: file bytes to a Z-up metre Motion (unit detection included)",
        "baselines": "bvh_pypi measured in this run on the same file (Bvh(text) construction); *_ref are "
                     "fairmotion 0.0.4 and bvhio 1.5.4 parse + FK on cmu_01_01 (2,752 frames) from "
                     "shared/notes/measured-here.md, not re-measured",
        "quick": str(bool(quick)),
    })
    return res


def _add_process_figures(res: BenchResult, tmp: Path, quick: bool, step) -> None:
    """The cold start (:func:`cold_start`) and the two figures timed in fresh processes or on big input."""
    cold = cold_start(tmp, repeats=3 if quick else 9)
    step()
    for k, v in _unit_speeds(tmp).items():
        res.add(k, v, "s")
    step()
    info = cold["info"]
    res.add("cold_info_s", info["s"], "s")
    res.add("cold_info_mb", info["mb"], "MB")
    res.baseline["goal_cold_info_s"] = _GOAL_COLD_INFO_S
    res.add("cold_info_cpu_s", info["cpu_s"], "s")
    note = (f"whole `kinodyn info` process on {cold['file']}, bytecode and numba caches warm: median "
            f"{info['s'] * 1e3:.0f} ms, best {info['best_s'] * 1e3:.0f} ms, CPU {info['cpu_s'] * 1e3:.0f} ms, "
            f"peak RSS {info['mb']:.0f} MB (a bare python: {cold['launcher_mb']:.0f} MB); load average "
            f"{cold['load']:.1f} on {os.cpu_count()} CPUs")
    if "bvh_pypi" in cold:
        pkg = cold["bvh_pypi"]
        res.add("cold_bvh_pypi_s", pkg["s"], "s")
        res.add("cold_ratio_vs_bvh_pypi", info["s"] / pkg["s"], "x")
        res.baseline["cold_bvh_pypi_s"] = pkg["s"]
        note += (f"; `python -c \"import bvh; bvh.Bvh(text)\"` on the same file: median {pkg['s'] * 1e3:.0f} ms, "
                 f"best {pkg['best_s'] * 1e3:.0f} ms, {pkg['mb']:.0f} MB (cold_ratio_vs_bvh_pypi = kinodyn / bvh)")
    res.notes["cold_start"] = note
