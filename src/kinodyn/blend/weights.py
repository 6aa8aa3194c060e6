"""Weights and ramps of the actions: activation (figure 2), priorities, the per-frame mix.

Ménardais, Multon, Kulpa, Arnaldi, support-phase synchronization, section 3. An action's weight ramps
up from 0 over ``ramp_in`` seconds after it starts (``t1 -> t2`` of figure 2) and down to 0 over
``ramp_out`` seconds after it is stopped (``t3 -> t4``), with a smoothstep. *Priorities* resolve the
weights: actions of a higher priority take the body first (their summed activation, capped at 1, is
their share), lower ones get what is left, and the neutral pose takes the remainder. Actions of the
same priority share by activation.

:func:`mix_weights` gives, for every character and slot, the action time of its frozen warp segment,
the clip time and the blend weight, compiled (:func:`_mix_weights_kernel`) or with the numpy functions
:func:`activation` and :func:`priority_weights` (the reference; same result).

Shapes: ``N`` characters, ``S`` action slots. Units: seconds.
"""

from __future__ import annotations

import numba
import numpy as np

from kinodyn.blend.timewarp import eval_poly

__all__ = ["activation", "mix_weights", "priority_weights", "smoothstep"]


def smoothstep(x):
    """``3x^2 - 2x^3`` on ``[0, 1]``, 0 below, 1 above."""
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def activation(t, t_on, ramp_in, t_off, ramp_out):
    """Activation level of actions at time ``t`` (figure 2): 0 before ``t_on``, up to 1 at ``t_on +
    ramp_in``, down from ``t_off`` to 0 at ``t_off + ramp_out``. Arrays broadcast; ``inf`` disables."""
    t = np.asarray(t, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        up = np.where(np.asarray(ramp_in) > 0, smoothstep((t - t_on) / np.maximum(ramp_in, 1e-12)),
                      (t >= t_on).astype(np.float64))
        down = np.where(np.asarray(ramp_out) > 0, smoothstep((t - t_off) / np.maximum(ramp_out, 1e-12)),
                        (t >= t_off).astype(np.float64))
    up = np.where(np.isfinite(t_on), up, 0.0)
    down = np.where(np.isfinite(t_off), down, 0.0)
    return up * (1.0 - down)


def priority_weights(act, prio) -> tuple[np.ndarray, np.ndarray]:
    """Blend weights from activations and priorities.

    Args:
        act: ``(N, S)`` activation levels in ``[0, 1]``.
        prio: ``(N, S)`` priorities (higher first); empty slots may hold any value with ``act = 0``.

    Returns:
        ``w (N, S)`` and the neutral pose's weight ``(N,)``; they sum to 1 per character. A priority
        level's share is ``min(1, sum of its activations)`` of what higher levels left, split among
        its actions in proportion to their activation.
    """
    act = np.asarray(act, dtype=np.float64)
    prio = np.asarray(prio, dtype=np.float64)
    same = prio[:, :, None] == prio[:, None, :]                      # (N, S, S)
    group = np.einsum("nst,nt->ns", same, act)                        # summed activation of s's level
    cover = np.minimum(group, 1.0)
    higher = prio[:, None, :] > prio[:, :, None]                      # t strictly above s
    # (1 - cover_t) once per higher level: average the log over the members of each level
    members = same.sum(axis=2)                                        # (N, S) size of each level
    with np.errstate(divide="ignore"):
        logfree = np.log(np.maximum(1.0 - cover, 0.0)) / members      # -inf when a level covers all
    logfree = np.where(np.isfinite(logfree), logfree, -np.inf)
    above = np.einsum("nst,nt->ns", higher, np.where(np.isfinite(logfree), logfree, 0.0))
    blocked = np.einsum("nst,nt->ns", higher, ~np.isfinite(logfree)) > 0
    rem = np.where(blocked, 0.0, np.exp(above))
    with np.errstate(invalid="ignore", divide="ignore"):
        w = np.where(group > 0, rem * cover * act / np.where(group > 0, group, 1.0), 0.0)
    return w, np.clip(1.0 - w.sum(axis=1), 0.0, 1.0)



@numba.njit(cache=True, inline="always")
def _ramp(t, start, duration):  # pragma: no cover - compiled
    """Smoothstep from 0 to 1 over ``[start, start + duration]``; 0 when ``start`` is not finite."""
    if not np.isfinite(start):
        return 0.0
    if duration > 0:
        x = min(max((t - start) / max(duration, 1e-12), 0.0), 1.0)
        return x * x * (3.0 - 2.0 * x)
    return 1.0 if t >= start else 0.0


@numba.njit(cache=True)
def _mix_weights_kernel(t, seg, speed, ramp, prio, h, tau, w, wn):  # pragma: no cover - compiled
    """Per character: action times ``h`` (the frozen warp segments), clip times ``tau``, activations and
    priority weights ``w``, ``wn`` (the arithmetic of eval_poly, activation and priority_weights)."""
    n_chars, n_slots = h.shape
    act = np.empty(n_slots)
    group = np.empty(n_slots)
    logf = np.empty(n_slots)
    for n in range(n_chars):
        for s in range(n_slots):
            t0 = seg[n, s, 0]
            u = min(max(t - t0, 0.0), max(seg[n, s, 1] - t0, 0.0))
            hh = ((seg[n, s, 5] * u + seg[n, s, 4]) * u + seg[n, s, 3]) * u + seg[n, s, 2]
            h[n, s] = hh
            tau[n, s] = hh * speed[n, s]
            act[s] = _ramp(t, ramp[n, s, 0], ramp[n, s, 1]) * (1.0 - _ramp(t, ramp[n, s, 2], ramp[n, s, 3]))
        for s in range(n_slots):
            # two interleaved partial sums, the order of numpy's einsum over the level
            a0 = 0.0
            a1 = 0.0
            members = 0
            for k in range(n_slots):
                v = act[k] if prio[n, k] == prio[n, s] else 0.0
                if k % 2 == 0:
                    a0 += v
                else:
                    a1 += v
                if prio[n, k] == prio[n, s]:
                    members += 1
            group[s] = a0 + a1
            free = max(1.0 - min(group[s], 1.0), 0.0)
            logf[s] = np.log(free) / members if free > 0.0 else -np.inf
        tot = 0.0
        for s in range(n_slots):
            a0 = 0.0
            a1 = 0.0
            blocked = False
            for k in range(n_slots):
                v = 0.0
                if prio[n, k] > prio[n, s]:
                    if np.isfinite(logf[k]):
                        v = logf[k]
                    else:
                        blocked = True
                if k % 2 == 0:
                    a0 += v
                else:
                    a1 += v
            g = group[s]
            if g > 0:
                rem = 0.0 if blocked else np.exp(a0 + a1)
                ws = rem * min(g, 1.0) * act[s] / g
            else:
                ws = 0.0
            w[n, s] = ws
            tot += ws
        wn[n] = min(max(1.0 - tot, 0.0), 1.0)


def mix_weights(t: float, seg, speed, ramp, prio, compiled: bool = True):
    """Action times, clip times and weights of every slot at time ``t``.

    Args:
        t: the time (s).
        seg: ``(N, S, 6)`` warp segments ``(t0, t1, c0, c1, c2, c3)``: the action time is the cubic
            ``c0 + c1 u + c2 u^2 + c3 u^3`` of ``u = clip(t - t0, 0, t1 - t0)``.
        speed: ``(N, S)`` time scalings (clip time = action time * speed).
        ramp: ``(N, S, 4)`` ``(t_on, ramp_in, t_off, ramp_out)`` (``inf``: not started / not stopped).
        prio: ``(N, S)`` priorities.
        compiled: the compiled kernel (True) or the numpy reference (same result).

    Returns:
        ``h (N, S)`` action times, ``tau (N, S)`` clip times, ``w (N, S)`` weights, ``wn (N,)`` the
        neutral pose's weight.
    """
    if compiled:
        N, S = speed.shape
        h, tau, w, wn = np.empty((N, S)), np.empty((N, S)), np.empty((N, S)), np.empty(N)
        _mix_weights_kernel(float(t), seg, speed, ramp, prio, h, tau, w, wn)
        return h, tau, w, wn
    u = np.clip(t - seg[..., 0], 0.0, np.maximum(seg[..., 1] - seg[..., 0], 0.0))
    h = eval_poly(seg[..., 2:6], u)
    tau = h * speed
    act = activation(t, ramp[..., 0], ramp[..., 1], ramp[..., 2], ramp[..., 3])
    w, wn = priority_weights(act, prio)
    return h, tau, w, wn
