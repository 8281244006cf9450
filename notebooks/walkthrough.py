# ---
# jupyter:
#   jupytext:
#     formats: py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
# ---

# %% [markdown]
# # kisscal walkthrough: from infrared fields to labelled trajectories
#
# This notebook (a jupytext "percent" script: open it in Jupyter with jupytext, or run it
# with `python notebooks/walkthrough.py`) walks through the stages of kisscal on a small
# synthetic KISS-like session, calling each stage's array functions directly. The test
# suite executes it. Set `KISSCAL_WALKTHROUGH_DIR` to keep the session and figures.

# %%
import os
import tempfile
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from kisscal import session
from kisscal.camera import Camera
from kisscal.detect import detect_blobs
from kisscal.detect.configure import configure_detection
from kisscal.dlt import calibrate_rods, make_rods
from kisscal.grid import apply_linearisation, linearise_frames
from kisscal.io.config import load_session
from kisscal.io.frames import camera_frames, trial_frames
from kisscal.recon import ReconParams, reconstruct_trial
from kisscal.rig import Rig
from kisscal.tracking import TrackingParams, build_trajectories

work = Path(os.environ.get("KISSCAL_WALKTHROUGH_DIR") or tempfile.mkdtemp(prefix="kisscal-"))
root = work / "session"
figures = work / "figures"
figures.mkdir(parents=True, exist_ok=True)

# %% [markdown]
# ## 1. A synthetic session
# Six cameras around a 1.4 x 2.4 x 2 m volume, 752 x 291 pixel fields at 50 Hz, a 40-field
# gait trial, grid and rod frames, and the ground truth in `truth/`.

# %%
if not (root / "session.toml").exists():
    session.synthesise(root, seed=11, fields=40, walking5=False, n_jobs=1)
config = load_session(root)
print(config.name, config.camera_ids, [t.name for t in config.trials])

# %% [markdown]
# ## 2. Blob detection (Shafiq et al. 2001, section 2)

# %%
frames = trial_frames(root, config.trial("walk01").images, config.camera_ids, "walk01")
# The camera-dependent settings (threshold, pixel aspect, size limits) come from a few of
# the camera's own frames; `kisscal run` does this per camera (out/detection/<camera>.json).
setup = configure_detection([frames["cam1"][i] for i in range(0, 40, 5)])
print(setup.summary())
image = frames["cam1"][20]
blobs = detect_blobs(image, setup.params)
print(f"{len(blobs)} blobs, {int(blobs.valid.sum())} valid")
fig, ax = plt.subplots(figsize=(9, 4))
ax.imshow(image, cmap="gray", aspect=2.0)
ax.plot(blobs.x_px[blobs.valid], blobs.y_px[blobs.valid], "g+", label="valid")
ax.plot(blobs.x_px[~blobs.valid], blobs.y_px[~blobs.valid], "rx", label="invalid (LED)")
ax.legend()
fig.savefig(figures / "detect.png")

# %% [markdown]
# ## 3. Grid linearisation (Küçük 2005, 2.2): 30 coefficients per camera

# %%
lins = {}
for cam in config.camera_ids:
    fit = linearise_frames(list(camera_frames(root, config.grid.images, cam, "grid")))
    lins[cam] = fit.linearisation
    q = fit.linearisation.quality
    print(f"{cam}: residual {q.residual_rms_before_px:.2f} -> {q.residual_rms_after_px:.3f} px")

# %% [markdown]
# ## 4. DLT calibration from the rods (Küçük 2005, 2.3)

# %%
rods = make_rods([(r.name, r.points_mm) for r in config.rods.rods])
rod_blobs = {}
for cam in config.camera_ids:
    rod_frames = list(camera_frames(root, config.rods.images, cam, "rod"))
    params = configure_detection(rod_frames).params
    rod_blobs[cam] = [
        apply_linearisation(lins[cam], detect_blobs(f, params).valid_only().xy_px)
        for f in rod_frames
    ]
cal = calibrate_rods(rod_blobs, rods)
for cam, res in cal.results.items():
    print(f"{cam}: rms {res.rms_px:.3f} px, centre {np.round(res.centre_mm)} mm")

# %% [markdown]
# ## 5. Matching and triangulation (Shafiq et al. 2001, 4.1-4.2)
# A `Rig` holds every camera's linearisation and DLT; it turns the blobs of a trial into
# the long table of linearised observations that reconstruction takes.

# %%
rig = Rig(tuple(Camera.from_dlt(cal.results[c].L, c, lins[c]) for c in config.camera_ids))
blobs = {}
for c in rig.ids:
    params = configure_detection([frames[c][i] for i in range(0, 40, 5)]).params
    blobs[c] = [detect_blobs(f, params).valid_only().xy_px for f in frames[c]]
obs = rig.observations(blobs)  # one row per blob: field, camera, linearised (u, v)
points = reconstruct_trial(obs.field, obs.camera, obs.uv_px, rig.dlts, ReconParams())
print(f"{len(points)} 3D points, median reprojection rms {np.median(points.rms_px):.3f} px")

# %% [markdown]
# ## 6. Tracking and labelling (Küçük 2005, 3.3.8-3.3.9)

# %%
result = build_trajectories(
    points.field, points.xyz_mm, TrackingParams(), config.markers.names, config.markers.template_mm
)
print(f"{len(result.labels)} trajectories: {', '.join(result.labels)}")
fig = plt.figure(figsize=(8, 4))
ax = fig.add_subplot(projection="3d")
for t, label in enumerate(result.labels):
    xyz = result.tracks.xyz_mm[result.tracks.track == t]
    ax.plot(xyz[:, 0], xyz[:, 1], xyz[:, 2], lw=1, label=label)
ax.legend(fontsize=6, ncol=3)
ax.set_xlabel("X mm")
ax.set_ylabel("Y mm")
ax.set_zlabel("Z mm")
fig.savefig(figures / "trajectories.png")

# %% [markdown]
# ## 7. The same in one call
# `kisscal run` does all of the above with caching, writes every output under `out/` and
# builds `out/report.html`.

# %%
summary = session.run(root)
print({t: v.get("trajectories") for t, v in summary["trials"].items()})
