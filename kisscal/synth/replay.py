"""Recorded trials replayed through a synthetic rig (the Vicon walking5.c3d).

:func:`replay_trial` moves a recorded trial into the control volume at the rig's field
rate, with capsules between its joint centres that occlude markers; for rigs that keep
every trial inside the volume, :func:`inside_volume` cuts it to the fields inside and
:func:`slim_capsules` keeps markers over a joint from hiding behind their own capsule.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from kisscal.synth.motion import Motion
from kisscal.synth.scene import segment_distance


def replay_trial(
    names: tuple[str, ...],
    xyz_mm: NDArray[np.float64],
    rate_hz: float,
    joint_centres_mm: dict[str, NDArray[np.float64]] | None = None,
    out_rate_hz: float = 50.0,
) -> Motion:
    """A recorded trial (e.g. the Vicon walking5.c3d) moved into the control volume.

    The trial is resampled from ``rate_hz`` to ``out_rate_hz`` (every k-th sample when the
    rates divide, linear interpolation otherwise; a sample next to a gap stays a gap),
    shifted so that the middle of its path lies at the centre of the volume's floor.
    Joint centres named ``{L,R}{HJC,KJC,AJC}`` give thigh and shank capsules for occlusion.
    """
    xyz = _resample(np.asarray(xyz_mm, dtype=float), rate_hz, out_rate_hz)
    mean_xy = np.nanmean(xyz[..., :2].reshape(-1, 2), axis=0)
    valid_x = np.where(np.isfinite(xyz[..., 0]), xyz[..., 0], np.nan)
    mid_x = 0.5 * (np.nanmin(valid_x) + np.nanmax(valid_x))
    shift = np.array([-mid_x, -mean_xy[1], 0.0])
    xyz = xyz + shift
    capsules, radii = [], []
    jc = joint_centres_mm or {}
    for s in "LR":
        for a, b, r in ((f"{s}HJC", f"{s}KJC", 65.0), (f"{s}KJC", f"{s}AJC", 45.0)):
            if a in jc and b in jc:
                ends = [_resample(jc[j], rate_hz, out_rate_hz) + shift for j in (a, b)]
                capsules.append(np.stack(ends, axis=1))
                radii.append(r)
    n = xyz.shape[0]
    caps = np.stack(capsules, axis=1) if capsules else np.zeros((n, 0, 2, 3))
    return Motion(
        names=tuple(names),
        xyz_mm=xyz,
        capsules_mm=np.nan_to_num(caps, nan=1e9),
        capsule_radius_mm=np.asarray(radii),
        rate_hz=out_rate_hz,
        segments=(),
    )


def _resample(samples: NDArray[np.float64], rate_hz: float, out_rate_hz: float) -> NDArray:
    """Samples (first axis: time) at ``out_rate_hz``; NaN stays NaN (gaps are not filled)."""
    samples = np.asarray(samples, dtype=float)
    ratio = rate_hz / out_rate_hz
    if abs(ratio - round(ratio)) < 1e-9:
        return samples[:: max(1, round(ratio))]
    t_in = np.arange(len(samples)) / rate_hz
    t_out = np.arange(int(np.floor(t_in[-1] * out_rate_hz)) + 1) / out_rate_hz
    k = np.clip(np.searchsorted(t_in, t_out, side="right") - 1, 0, len(samples) - 2)
    w = ((t_out - t_in[k]) * rate_hz).reshape(-1, *([1] * (samples.ndim - 1)))
    return (1 - w) * samples[k] + w * samples[k + 1]


def slim_capsules(motion: Motion, clearance_mm: float = 10.0, least_mm: float = 20.0) -> Motion:
    """``motion`` with capsule radii shrunk so that no marker lies inside its own capsule.

    A recorded trial's joint-centre capsules (:func:`replay_trial`) have nominal radii; a
    marker on the skin over a joint (a femoral condyle, a malleolus) can lie closer to the
    bone axis than that and would then hide behind its own capsule in every camera. Each
    radius becomes at most the median distance (over fields) of the nearest marker to the
    capsule's axis, less ``clearance_mm`` (never below ``least_mm``).
    """
    caps = motion.capsules_mm  # (F, K, 2, 3)
    if caps.shape[1] == 0:
        return motion
    xyz = motion.xyz_mm[:, :, None, :]  # (F, M, 1, 3)
    d = segment_distance(xyz, xyz, caps[:, None, :, 0, :], caps[:, None, :, 1, :])
    nearest = np.nanmin(np.nanmedian(d, axis=0), axis=0)  # (K,)
    radius = np.maximum(np.minimum(motion.capsule_radius_mm, nearest - clearance_mm), least_mm)
    return dataclasses.replace(motion, capsule_radius_mm=radius)


def inside_volume(motion: Motion, volume_mm: tuple, max_fields: int) -> Motion:
    """The longest run of fields whose markers all lie inside ``volume_mm`` (at most
    ``max_fields`` of them, from its middle): a recorded walk cut to what the lab sees."""
    lo, hi = np.asarray(volume_mm[0], dtype=float), np.asarray(volume_mm[1], dtype=float)
    xyz = motion.xyz_mm
    exists = np.all(np.isfinite(xyz), axis=-1)
    safe = np.where(exists[..., None], xyz, (lo + hi) / 2)
    inside = np.all((safe >= lo) & (safe <= hi), axis=(1, 2)) & exists.any(axis=1)
    edges = np.flatnonzero(np.diff(np.r_[0, inside.astype(int), 0]))
    if len(edges) == 0:
        raise ValueError("no field of the recorded trial lies inside the volume")
    starts, stops = edges[::2], edges[1::2]
    longest = int(np.argmax(stops - starts))
    start, stop = int(starts[longest]), int(stops[longest])
    excess = max(0, (stop - start) - max_fields)
    start, stop = start + excess // 2, stop - (excess - excess // 2)
    return dataclasses.replace(
        motion, xyz_mm=xyz[start:stop], capsules_mm=motion.capsules_mm[start:stop]
    )
