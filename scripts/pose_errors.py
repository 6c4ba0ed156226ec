#!/usr/bin/env python3
"""How far a fit's refined poses are from the truth of a `relume synth --imperfect pose=...` capture.

    scripts/pose_errors.py WORK/result/frames.json CAPTURE/gt/imperfections.json

Prints, over the frames the fit kept (in the capture's order, which is the kept training frames'
order of gt/imperfections.json), the median and 90th percentile of the position and rotation errors
of the written poses and of the refined ones, and how many frames the refinement made worse.
"""
import json
import sys

import numpy as np


def rotation_and_position(m):
    m = np.asarray(m, dtype=float)
    return m[:3, :3], m[:3, 3]


def errors(a, b):
    ra, pa = rotation_and_position(a)
    rb, pb = rotation_and_position(b)
    cos = (np.trace(ra @ rb.T) - 1) / 2
    return np.linalg.norm(pa - pb), np.degrees(np.arccos(np.clip(cos, -1, 1)))


def main():
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    fit = json.load(open(sys.argv[1]))
    truth = [f for f in json.load(open(sys.argv[2]))["frames"] if not f["left_out"]]
    refined = fit.get("poses", {}).get("frames")
    if refined is None:
        sys.exit(f"{sys.argv[1]}: no refined poses (refine_poses was off)")
    if len(refined) != len(truth):
        sys.exit(f"{len(refined)} frames in the fit, {len(truth)} in the truth")
    before, after = [], []
    for f, t in zip(refined, truth):
        if f["dropped"]:
            continue
        before.append(errors(t["written_transform_matrix"], t["true_transform_matrix"]))
        after.append(errors(f["transform_matrix"], t["true_transform_matrix"]))
    before, after = np.array(before), np.array(after)
    worse = int(np.sum((after[:, 0] > before[:, 0]) & (after[:, 1] > before[:, 1])))
    for name, e in (("written", before), ("refined", after)):
        print(f"{name}: position median {1e3 * np.median(e[:, 0]):.2f} mm (90%: {1e3 * np.percentile(e[:, 0], 90):.2f}), "
              f"rotation median {np.median(e[:, 1]):.3f} deg (90%: {np.percentile(e[:, 1], 90):.3f})")
    print(f"frames: {len(after)} kept, {worse} worse in both position and rotation, "
          f"{sum(f['dropped'] for f in refined)} dropped")


if __name__ == "__main__":
    main()
