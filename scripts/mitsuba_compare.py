#!/usr/bin/env python3
"""Mitsuba 3 side of scripts/mitsuba_compare.sh (pip install mitsuba; CPU variant scalar_rgb).

render SCENE_XML TRANSFORMS OUT_DIR --spp N --seed S
  Loads `relume export --mitsuba`'s scene.xml as is (its integrator: path, max_depth = relume's
  depth + 1, no Russian roulette) and renders every camera of a transforms.json (OpenGL axes;
  Mitsuba's camera looks along +z with +x to the left, so to_world = c2w * diag(-1, 1, -1)) with a
  box pixel filter like relume's. Writes OUT_DIR/<frame stem>.exr.

compare TRANSFORMS NAMES_JSON RELUME_A RELUME_B MITSUBA_A MITSUBA_B
  Per object: mean radiance over pixels whose 3x3 neighbourhood is that object in relume's object
  AOV (same geometry, same cameras), pooled over views; A and B are independent renders, so the
  standard error of a mean is sqrt(sum (A - B)^2) / (2 n). Prints relume / Mitsuba per object.
"""
import argparse, json, math, os, sys

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")


def frames(transforms_path):
    t = json.load(open(transforms_path))
    for fr in t["frames"]:
        get = lambda k: float(fr.get(k, t.get(k)))
        stem = os.path.splitext(os.path.basename(fr["file_path"]))[0]
        yield stem, fr, get


def render(a):
    scene = mi.load_file(a.scene_xml)
    os.makedirs(a.out, exist_ok=True)
    for stem, fr, get in frames(a.transforms):
        w, h = int(get("w")), int(get("h"))
        c2w = np.array(fr["transform_matrix"], dtype=float) @ np.diag([-1.0, 1.0, -1.0, 1.0])
        fov = math.degrees(2 * math.atan(w / (2 * get("fl_x"))))
        sensor = mi.load_dict({
            "type": "perspective", "fov": fov, "fov_axis": "x", "to_world": mi.ScalarTransform4f(c2w.tolist()),
            "principal_point_offset_x": (get("cx") - w / 2) / w, "principal_point_offset_y": (get("cy") - h / 2) / h,
            "sampler": {"type": "independent", "sample_count": a.spp, "seed": a.seed},
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        })
        img = mi.render(scene, sensor=sensor, spp=a.spp, seed=a.seed)
        mi.Bitmap(img).write(os.path.join(a.out, stem + ".exr"))


def load(path):
    return np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]


def compare(a):
    names = {o["id"]: o["name"] for o in json.load(open(a.names))["objects"]}
    acc = {}
    for stem, _, _ in frames(a.transforms):
        ra, rb = load(os.path.join(a.relume_a, stem + ".exr")), load(os.path.join(a.relume_b, stem + ".exr"))
        ma, mb = load(os.path.join(a.mitsuba_a, stem + ".exr")), load(os.path.join(a.mitsuba_b, stem + ".exr"))
        ids = np.rint(load(os.path.join(a.relume_a, stem + "_object.exr"))[:, :, 0]).astype(int)
        h, w = ids.shape
        inner = ids[1:-1, 1:-1]
        same = np.ones_like(inner, dtype=bool)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                same &= ids[1 + dy:h - 1 + dy, 1 + dx:w - 1 + dx] == inner
        for oid in np.unique(inner[same & (inner >= 0)]):
            sel = np.zeros_like(ids, dtype=bool)
            sel[1:-1, 1:-1] = same & (inner == oid)
            e = acc.setdefault(int(oid), np.zeros((5, 3)))
            e[0] += sel.sum()
            e[1] += ((ra + rb) / 2)[sel].sum(0)
            e[2] += ((ma + mb) / 2)[sel].sum(0)
            e[3] += ((ra - rb) ** 2)[sel].sum(0)
            e[4] += ((ma - mb) ** 2)[sel].sum(0)
    print("%-16s %6s %10s %10s %8s %8s %8s %8s" % ("object", "pixels", "relume", "mitsuba", "ratio", "se", "r/m red", "r/m blue"))
    for oid in sorted(acc):
        n, sr, sm, vr, vm = acc[oid]
        n = n[0]
        mr, mm = sr.sum() / (3 * n), sm.sum() / (3 * n)
        if min(mr, mm, sm[0], sm[2]) <= 0:
            print("%-16s %6d %10.5f %10.5f (no light)" % (names.get(oid, oid), n, mr, mm))
            continue
        ser, sem = math.sqrt(vr.sum() / 3) / (2 * n), math.sqrt(vm.sum() / 3) / (2 * n)
        ratio = mr / mm
        print("%-16s %6d %10.5f %10.5f %8.4f %8.4f %8.4f %8.4f" % (names.get(oid, oid), n, mr, mm, ratio,
              ratio * math.hypot(ser / mr, sem / mm), sr[0] / sm[0], sr[2] / sm[2]))


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else ""
    ap = argparse.ArgumentParser(prog="mitsuba_compare.py " + mode)
    if mode == "render":
        for k in ("scene_xml", "transforms", "out"):
            ap.add_argument(k)
        ap.add_argument("--spp", type=int, default=256)
        ap.add_argument("--seed", type=int, default=1)
        render(ap.parse_args(sys.argv[2:]))
    elif mode == "compare":
        for k in ("transforms", "names", "relume_a", "relume_b", "mitsuba_a", "mitsuba_b"):
            ap.add_argument(k)
        compare(ap.parse_args(sys.argv[2:]))
    else:
        sys.exit("mitsuba_compare.py: mode must be render or compare, not '%s'" % mode)


main()
