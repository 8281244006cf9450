"""Blob detection speed on a synthetic 6-camera x 500-field gait trial.

Reference, timed in the same run on the same images: ``cv2.threshold`` +
``cv2.connectedComponentsWithStats`` (8-connected) with its centroids, i.e. the cheapest
"find the spots" a library offers, without any of kisscal's noise removal, advanced tests
or weighted centroids. Both run on one thread (OpenCV pinned with ``cv2.setNumThreads(1)``)
and then on all cores (kisscal with :func:`kisscal.detect.detect_sequence` processes,
OpenCV on a thread pool of the same size). The PNG decoding time of the same fields is
reported too: it is the floor of any pipeline that starts from image files.

Environment: ``KISSCAL_BENCH_FIELDS`` (default 500) fields per camera.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import cv2
import numpy as np

from benchmarks._harness import Timing, best_of, best_of_pair, report
from kisscal.detect import Blobs, DetectionParams, detect_blobs, detect_sequence
from kisscal.detect.configure import configure_detection
from kisscal.synth.plan import SynthOptions, plan_session, render_trial
from kisscal.synth.scene import FieldTruth


def _fields(
    n_fields: int, seed: int = 1
) -> tuple[list[np.ndarray], list[FieldTruth], list[DetectionParams]]:
    """The rendered fields of every camera, their truth, and each field's camera settings.

    Detection settings are derived per camera from a sample of its fields, as a session
    derives them (``out/detection/<camera>.json``).
    """
    plan = plan_session(SynthOptions(seed=seed, fields=n_fields))
    images, truths, params = [], [], []
    for cam in range(len(plan.rig)):
        rendered = list(render_trial(plan, "walk01", cam))
        sample = [r[1] for r in rendered[:: max(1, len(rendered) // 24)]]
        setting = configure_detection(sample).params
        images += [r[1] for r in rendered]
        truths += [r[2] for r in rendered]
        params += [setting] * len(rendered)
    return images, truths, params


def _accuracy(blobs: list[Blobs], truths: list[FieldTruth]) -> str:
    """Recall, precision and isolated-marker centroid RMS against the rig's truth.

    Same rules as tests/detect/test_rig.py: a marker is found by a valid blob within half
    its radius (round units); recall counts markers at least one radius from any other.
    """
    markers = found = valid_blobs = true_blobs = 0
    errors: list[float] = []
    for b, truth in zip(blobs, truths, strict=True):
        valid = b.valid_only()
        uv = truth.uv_px[truth.visible]
        r = truth.radii_px[truth.visible]
        iso = truth.isolated[truth.visible]
        apart = np.hypot(
            (uv[:, None, 0] - uv[None, :, 0]) / r[:, None, 0],
            (uv[:, None, 1] - uv[None, :, 1]) / r[:, None, 1],
        )
        np.fill_diagonal(apart, np.inf)
        separate = apart.min(axis=1, initial=np.inf) >= 1.0
        markers += int(separate.sum())
        valid_blobs += len(valid)
        if len(valid) == 0 or len(uv) == 0:
            continue
        d = np.hypot(
            (valid.x_px[:, None] - uv[:, 0]) / r[:, 0], (valid.y_px[:, None] - uv[:, 1]) / r[:, 1]
        )
        nearest = d.argmin(axis=0)
        ok = d[nearest, np.arange(len(uv))] < 0.5
        found += int((ok & separate).sum())
        marker_of = d.argmin(axis=1)
        true_blobs += np.unique(marker_of[d[np.arange(len(valid)), marker_of] < 0.5]).size
        j = np.flatnonzero(iso & ok)
        errors += np.hypot(
            valid.x_px[nearest[j]] - uv[j, 0], valid.y_px[nearest[j]] - uv[j, 1]
        ).tolist()
    rms = float(np.sqrt(np.mean(np.square(errors)))) if errors else float("nan")
    return (
        f"accuracy: recall {100 * found / max(markers, 1):.2f} % of {markers} markers, "
        f"precision {100 * true_blobs / max(valid_blobs, 1):.2f} % of {valid_blobs} valid "
        f"blobs, isolated centroid rms {rms:.4f} px ({len(errors)} markers)"
    )


def _opencv(image: np.ndarray, threshold: int) -> np.ndarray:
    _, white = cv2.threshold(image, threshold - 1, 1, cv2.THRESH_BINARY)
    _, _, stats, centroids = cv2.connectedComponentsWithStats(white, connectivity=8)
    return np.column_stack([centroids[1:], stats[1:, cv2.CC_STAT_AREA]])


def main() -> list[str]:
    n_fields = int(os.environ.get("KISSCAL_BENCH_FIELDS", "500"))
    images, truths, settings = _fields(n_fields)
    n = len(images)
    params = settings[0]  # every camera of the rig gets about the same settings
    threshold = int(params.threshold)
    cores = os.cpu_count() or 1
    lines = [f"{n} fields (6 cameras x {n_fields}), 752 x 291 px, {cores} cores"]

    previous = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        ref, ours = best_of_pair(
            (
                "opencv CC+centroids, 1 thread",
                lambda: [_opencv(im, threshold) for im in images],
            ),
            (
                "kisscal detect_blobs, 1 thread",
                lambda: [detect_blobs(im, p) for im, p in zip(images, settings, strict=True)],
            ),
            n,
            "fields",
        )
        lines += [report(ref), report(ours, ref)]
        if cores > 1:
            with ThreadPoolExecutor(cores) as pool:
                ref_n = best_of(
                    f"opencv CC+centroids, {cores} threads",
                    lambda: list(pool.map(lambda im: _opencv(im, threshold), images)),
                    n,
                    "fields",
                )
            ours_n = best_of(
                f"kisscal detect_sequence, {cores} procs",
                lambda: detect_sequence(images, params, workers=cores, chunksize=64),
                n,
                "fields",
            )
            lines += [report(ref_n), report(ours_n, ref_n)]
        pngs = [cv2.imencode(".png", im)[1] for im in images]
        decode = best_of(
            "PNG decode (cv2.imdecode), 1 thread",
            lambda: [cv2.imdecode(p, cv2.IMREAD_UNCHANGED) for p in pngs],
            n,
            "fields",
        )
        lines.append(report(decode, ours))
        lines.append(
            f"per field: kisscal {1e6 * ours.seconds / n:.0f} us, opencv "
            f"{1e6 * ref.seconds / n:.0f} us, PNG decode {1e6 * decode.seconds / n:.0f} us"
        )
        lines.append(_summary(ours, ref))
        found = [detect_blobs(im, p) for im, p in zip(images, settings, strict=True)]
        lines.append(_accuracy(found, truths))
    finally:
        cv2.setNumThreads(previous)
    return lines


def _summary(ours: Timing, ref: Timing) -> str:
    ratio = ours.seconds / ref.seconds
    verdict = "met" if ratio <= 0.5 else "NOT met"
    return f"full analysis / opencv CC = {ratio:.2f} (issue 18 bar: 0.5 at 1 thread: {verdict})"
