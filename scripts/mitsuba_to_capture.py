#!/usr/bin/env python3
"""Converts a Mitsuba 0.5/0.6 XML interior into what relume reads: one PLY (binary, positions,
vertex normals when the source has them, a per-face `object_id` = the index of the source
<shape>), objects.json (shape names), and scene.json (per-object constant albedo from diffuse
reflectances, area emitters as object emission) so `relume render` can synthesise a capture.

Reads the scene from a git mirror (`--git DIR`, objects read with `git show HEAD:path`) or from a
folder. Shapes whose file is missing (large files absent from a snapshot) are skipped and listed.
Supported shapes: obj, ply (ascii / binary little endian), serialized (Mitsuba's zlib format,
with shapeIndex), rectangle (area-light windows). Transforms: translate, scale, rotate, matrix,
lookat; a mirroring transform keeps the front side. `--materials bsdf` maps each BSDF to relume's
principled-v1 (diffuse: roughness 1, specular 0; plastic: specular 0.5; conductors, which relume
cannot represent: albedo 0.04, specular 1; zero-transmittance dielectrics: opaque glossy black;
textured reflectance: the texture's mean linear colour) and writes materials_source.json.

The White Room (docs/notes/2026-11-25-light-sources.md):
    python3 scripts/mitsuba_to_capture.py --git /work/.mirror/hchoi405+dppm-scenes/repo \
        --xml scenes/living-room-2/scene.xml --scale 1 --out whiteroom --frames 48 --width 256 \
        --height 192 --test-frames 8 --sweep 60 --materials bsdf
then objects 179-181 named window_bay_centre/left/right and the back window (182, behind every
camera) switched off in scene.json, and `SOURCE=whiteroom scripts/cycles_capture.sh OUT`.

    python3 scripts/mitsuba_to_capture.py --git /work/.mirror/VElysianP+mitsuba_scenes/repo \
        --xml statler_elevatorroom/elevatorRoom_statler_revised.xml --scale 0.01 --out scenes/statler
"""
import argparse
import json
import math
import os
import struct
import subprocess
import sys
import xml.etree.ElementTree as ET
import zlib

import numpy as np


class Source:
    def __init__(self, git, root):
        self.git, self.root = git, root

    def read(self, path):
        path = os.path.normpath(path)
        if self.git:
            r = subprocess.run(["git", "-C", self.git, "show", f"HEAD:{path}"], capture_output=True)
            return r.stdout if r.returncode == 0 else None
        full = os.path.join(self.root, path)
        return open(full, "rb").read() if os.path.exists(full) else None


def read_obj(data):
    v, vn, faces = [], [], []
    for line in data.decode("utf-8", "replace").splitlines():
        if line.startswith("v "):
            v.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("vn "):
            vn.append([float(x) for x in line.split()[1:4]])
        elif line.startswith("f "):
            corners = []
            for c in line.split()[1:]:
                parts = c.split("/")
                vi = int(parts[0])
                ni = int(parts[2]) if len(parts) > 2 and parts[2] else 0
                corners.append((vi - 1 if vi > 0 else len(v) + vi, (ni - 1 if ni > 0 else len(vn) + ni) if ni else -1))
            for k in range(1, len(corners) - 1):  # fan, like relume's own OBJ reader
                faces.append((corners[0], corners[k], corners[k + 1]))
    # One output vertex per distinct (position, normal) pair.
    key = {}
    pos, nrm, tris = [], [], []
    has_n = len(vn) > 0
    for f in faces:
        t = []
        for c in f:
            if c not in key:
                key[c] = len(pos)
                pos.append(v[c[0]])
                nrm.append(vn[c[1]] if has_n and c[1] >= 0 else [0.0, 0.0, 0.0])
            t.append(key[c])
        tris.append(t)
    return np.array(pos, np.float64).reshape(-1, 3), (np.array(nrm, np.float64).reshape(-1, 3) if has_n else None), \
        np.array(tris, np.int64).reshape(-1, 3)


PLY_TYPES = {"char": "i1", "uchar": "u1", "int8": "i1", "uint8": "u1", "short": "i2", "ushort": "u2", "int16": "i2",
             "uint16": "u2", "int": "i4", "uint": "u4", "int32": "i4", "uint32": "u4", "float": "f4", "float32": "f4",
             "double": "f8", "float64": "f8"}


def read_ply(data):
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode("ascii", "replace").splitlines()
    fmt = [l.split()[1] for l in header if l.startswith("format")][0]
    elements = []
    for l in header:
        w = l.split()
        if w and w[0] == "element":
            elements.append([w[1], int(w[2]), []])
        elif w and w[0] == "property":
            elements[-1][2].append(w[1:])
    body = data[end:]
    out = {}
    if fmt == "ascii":
        tokens = body.split()
        at = 0
        for name, count, props in elements:
            rows = []
            for _ in range(count):
                row = []
                for p in props:
                    if p[0] == "list":
                        n = int(tokens[at]); at += 1
                        row.append([float(x) for x in tokens[at:at + n]]); at += n
                    else:
                        row.append(float(tokens[at])); at += 1
                rows.append(row)
            out[name] = (props, rows)
    else:
        bo = "<" if fmt == "binary_little_endian" else ">"
        at = 0
        for name, count, props in elements:
            if all(p[0] != "list" for p in props):
                dt = np.dtype([(p[1], bo + PLY_TYPES[p[0]]) for p in props])
                arr = np.frombuffer(body, dt, count, at)
                at += dt.itemsize * count
                out[name] = (props, arr)
            else:
                rows = []
                for _ in range(count):
                    row = []
                    for p in props:
                        if p[0] == "list":
                            ct, it = bo + PLY_TYPES[p[1]], bo + PLY_TYPES[p[2]]
                            n = int(np.frombuffer(body, ct, 1, at)[0]); at += np.dtype(ct).itemsize
                            row.append(np.frombuffer(body, it, n, at).tolist()); at += np.dtype(it).itemsize * n
                        else:
                            t = bo + PLY_TYPES[p[0]]
                            row.append(float(np.frombuffer(body, t, 1, at)[0])); at += np.dtype(t).itemsize
                    rows.append(row)
                out[name] = (props, rows)
    vprops, vrows = out["vertex"]
    names = [p[-1] for p in vprops]

    def col(n):
        if isinstance(vrows, np.ndarray):
            return vrows[n].astype(np.float64)
        return np.array([r[names.index(n)] for r in vrows], np.float64)

    pos = np.stack([col("x"), col("y"), col("z")], 1)
    nrm = np.stack([col("nx"), col("ny"), col("nz")], 1) if "nx" in names else None
    fprops, frows = out["face"]
    li = [i for i, p in enumerate(fprops) if p[0] == "list"][0]
    tris = []
    for r in frows:
        idx = [int(x) for x in r[li]]
        for k in range(1, len(idx) - 1):
            tris.append((idx[0], idx[k], idx[k + 1]))
    return pos, nrm, np.array(tris, np.int64).reshape(-1, 3)


def read_serialized(data, index):
    magic, version = struct.unpack_from("<HH", data, 0)
    if magic != 0x041C:
        raise ValueError("not a Mitsuba serialized mesh")
    count = struct.unpack_from("<I", data, len(data) - 4)[0]
    if version >= 4:
        offsets = struct.unpack_from(f"<{count}Q", data, len(data) - 4 - 8 * count)
    else:
        offsets = struct.unpack_from(f"<{count}I", data, len(data) - 4 - 4 * count)
    start = offsets[index]
    stop = offsets[index + 1] if index + 1 < count else len(data) - 4 - (8 if version >= 4 else 4) * count
    raw = zlib.decompress(data[start + 4:stop])
    flags = struct.unpack_from("<I", raw, 0)[0]
    at = 4
    if version >= 4:
        at = raw.index(b"\0", at) + 1
    nv, nt = struct.unpack_from("<QQ", raw, at)
    at += 16
    fdt = "<f8" if flags & 0x2000 else "<f4"
    fs = 8 if flags & 0x2000 else 4
    pos = np.frombuffer(raw, fdt, nv * 3, at).reshape(-1, 3).astype(np.float64); at += nv * 3 * fs
    nrm = None
    if flags & 0x0001:
        nrm = np.frombuffer(raw, fdt, nv * 3, at).reshape(-1, 3).astype(np.float64); at += nv * 3 * fs
    if flags & 0x0002:
        at += nv * 2 * fs
    if flags & 0x0008:
        at += nv * 3 * fs
    idt = "<u8" if nt * 3 > 0xFFFFFFFF else "<u4"
    tris = np.frombuffer(raw, idt, nt * 3, at).reshape(-1, 3).astype(np.int64)
    return pos, nrm, tris


def floats(s):
    return [float(x) for x in s.replace(",", " ").split()]


def parse_transform(node):
    m = np.eye(4)
    for t in node:
        tag = t.tag
        a = t.attrib
        if tag == "translate":
            x = np.eye(4)
            x[:3, 3] = [float(a.get("x", 0)), float(a.get("y", 0)), float(a.get("z", 0))]
        elif tag == "scale":
            if "value" in a:
                s = [float(a["value"])] * 3
            else:
                s = [float(a.get("x", 1)), float(a.get("y", 1)), float(a.get("z", 1))]
            x = np.diag(s + [1.0])
        elif tag == "rotate":
            axis = np.array([float(a.get("x", 0)), float(a.get("y", 0)), float(a.get("z", 0))])
            axis /= np.linalg.norm(axis)
            ang = math.radians(float(a["angle"]))
            k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
            x = np.eye(4)
            x[:3, :3] = np.eye(3) + math.sin(ang) * k + (1 - math.cos(ang)) * k @ k
        elif tag == "matrix":
            x = np.array(floats(a["value"])).reshape(4, 4)
        elif tag == "lookat":
            o, tg = np.array(floats(a["origin"])), np.array(floats(a["target"]))
            up = np.array(floats(a.get("up", "0 1 0")))
            d = (tg - o) / np.linalg.norm(tg - o)
            left = np.cross(up, d); left /= np.linalg.norm(left)
            nu = np.cross(d, left)
            x = np.eye(4)
            x[:3, 0], x[:3, 1], x[:3, 2], x[:3, 3] = left, nu, d, o
        else:
            continue
        m = x @ m
    return m


def scaled_translation(m, scale):
    m = np.array(m)
    m[:3, 3] *= scale
    return m.tolist()


def transparent(bsdf, bsdfs):
    """True for (rough/thin) dielectrics, directly or under twosided/ref: relume is opaque-only, so
    such shapes (lamp glass, bottles' glass) are left out instead of becoming opaque occluders."""
    if bsdf is None:
        return False
    if bsdf.tag == "ref":
        return transparent(bsdfs.get(bsdf.attrib.get("id")), bsdfs)
    if bsdf.attrib.get("type") in ("dielectric", "roughdielectric", "thindielectric"):
        t = bsdf.find("*[@name='specularTransmittance']")
        if t is not None and max(floats(t.attrib["value"])) == 0.0:
            return False  # zero transmittance: an opaque, glossy black surface (TV screen, black marble)
        return True
    return any(transparent(c, bsdfs) for c in bsdf if c.tag in ("bsdf", "ref"))


def reflectance(bsdf, bsdfs):
    """A diffuse colour for the shape's bsdf (nested twosided etc.), else None."""
    if bsdf is None:
        return None
    if bsdf.tag == "ref":
        return reflectance(bsdfs.get(bsdf.attrib.get("id")), bsdfs)
    for c in bsdf:
        if c.tag in ("srgb", "rgb") and c.attrib.get("name") in ("reflectance", "diffuseReflectance"):
            v = floats(c.attrib["value"]) if not c.attrib["value"].startswith("#") else None
            if v:
                v = v * 3 if len(v) == 1 else v
                if c.tag == "srgb":
                    v = [x / 12.92 if x <= 0.04045 else ((x + 0.055) / 1.055) ** 2.4 for x in v]
                return [min(max(x, 0.0), 0.95) for x in v[:3]]
        if c.tag == "bsdf":
            r = reflectance(c, bsdfs)
            if r:
                return r
    return None


def inner_bsdf(bsdf, bsdfs):
    """the BSDF under twosided / mask / bumpmap / ref wrappers."""
    while bsdf is not None:
        if bsdf.tag == "ref":
            bsdf = bsdfs.get(bsdf.attrib.get("id"))
            continue
        if bsdf.attrib.get("type") in ("twosided", "mask", "bumpmap"):
            bsdf = bsdf.find("bsdf")
            continue
        return bsdf
    return None


def texture_mean(bsdf, src, base):
    """mean linear colour of a bitmap reflectance texture, or None."""
    if bsdf is None:
        return None
    for t in bsdf.iter("texture"):
        if t.attrib.get("type") == "bitmap" and t.attrib.get("name") in ("reflectance", "diffuseReflectance"):
            fn = t.find("string[@name='filename']")
            data = src.read(os.path.join(base, fn.attrib["value"])) if fn is not None else None
            if data is None:
                return None
            import io
            from PIL import Image
            im = np.asarray(Image.open(io.BytesIO(data)).convert("RGB"), np.float64) / 255.0
            lin = np.where(im <= 0.04045, im / 12.92, ((im + 0.055) / 1.055) ** 2.4)
            return [round(min(max(float(x), 0.0), 0.95), 4) for x in lin.reshape(-1, 3).mean(0)]
    return None


def bsdf_material(bsdf, bsdfs, src, base):
    """(albedo or None, roughness, specular, kind) for relume's principled-v1 with metallic 0:
    roughness = sqrt(Mitsuba alpha) (GGX alpha = r^2); plastic / dielectric ior 1.5: F0 0.04 = specular
    0.5; diffuse: roughness 1, specular 0; conductors (no metallic in relume): dark albedo 0.04, specular 1
    (F0 0.08, the most principled-v1 allows), roughness from alpha."""
    b = inner_bsdf(bsdf, bsdfs)
    kind = b.attrib.get("type") if b is not None else "none"
    a = b.find("float[@name='alpha']") if b is not None else None
    alpha = float(a.attrib["value"]) if a is not None else 0.0
    rough = round(min(max(math.sqrt(alpha), 0.035), 1.0), 3)
    if kind == "diffuse":
        return None, 1.0, 0.0, kind
    if kind in ("plastic", "roughplastic"):
        return None, rough, 0.5, kind
    if kind in ("conductor", "roughconductor"):
        return [0.04, 0.04, 0.04], rough, 1.0, kind
    if kind in ("dielectric", "roughdielectric"):
        return [0.01, 0.01, 0.01], rough, 0.5, kind
    return None, 0.6, 0.3, kind


def write_cameras(args, sensor):
    """transforms.json (nerfstudio: camera-to-world with x right, y up, z back) for a yaw sweep
    around the Mitsuba sensor (x left, y up, z forward), images/NN.exr to be rendered; with
    --test-frames, transforms_test.json too (test/NN.exr), its cameras spread over the same sweep
    between the training ones, so every held-out view is a novel one."""
    m = np.array(sensor["to_world"])
    rot = m[:3, :3] / np.linalg.norm(m[:3, :3], axis=0)
    up = rot[:, 1]
    k = np.array([[0, -up[2], up[1]], [up[2], 0, -up[0]], [-up[1], up[0], 0]])

    def frame(t, path):  # t in [-0.5, 0.5]: position along the sweep
        ang = math.radians(args.sweep * t)
        yaw = np.eye(3) + math.sin(ang) * k + (1 - math.cos(ang)) * k @ k
        c2w = np.eye(4)
        c2w[:3, :3] = yaw @ rot @ np.diag([-1.0, 1.0, -1.0])
        c2w[:3, 3] = m[:3, 3] + 0.2 * t * rot[:, 0]
        return {"file_path": path, "transform_matrix": c2w.tolist()}

    fl = 0.5 * args.width / math.tan(math.radians(sensor["fov"]) / 2)
    intrinsics = {"camera_model": "PINHOLE", "fl_x": fl, "fl_y": fl, "cx": args.width / 2, "cy": args.height / 2,
                  "w": args.width, "h": args.height}
    step = 1.0 / max(args.frames - 1, 1)
    sets = [("transforms.json", "images", [i * step - 0.5 for i in range(args.frames)])]
    if args.test_frames:
        # Halfway between two neighbouring training cameras, in gaps spread evenly over the sweep.
        gaps = [(i * 2 + 1) * (args.frames - 1) // (2 * args.test_frames) for i in range(args.test_frames)]
        sets.append(("transforms_test.json", "test", [(g + 0.5) * step - 0.5 for g in gaps]))
    for name, folder, ts in sets:
        frames = [frame(t, f"{folder}/{i:02d}.exr") for i, t in enumerate(ts)]
        with open(os.path.join(args.out, name), "w") as f:
            json.dump({**intrinsics, "frames": frames}, f, indent=1)


def object_materials(objects, args):
    """Per-object roughness and specular, and albedo where the source gives none (a texture):
    the source's look (uniform 0.6 / 0.3, grey), or with --materials varied, values drawn per object
    from --seed, so a reconstruction has distinct materials to find."""
    rng = np.random.default_rng(args.seed)
    out = []
    for o in objects:
        draw = rng.uniform(size=5)
        if args.materials == "bsdf":
            out.append((o["albedo"] or [0.5, 0.5, 0.5], o["roughness"], o["specular"]))
            continue  # drawn for every object, so one object's values never depend on another's source
        if args.materials == "varied":
            albedo = o["albedo"] or [round(0.05 + 0.8 * x, 3) for x in draw[:3]]
            out.append((albedo, round(0.15 + 0.8 * draw[3], 3), round(0.1 + 0.8 * draw[4], 3)))
        else:
            out.append((o["albedo"] or [0.5, 0.5, 0.5], 0.6, 0.3))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--git", help="git directory of a mirror (files read from HEAD)")
    ap.add_argument("--root", help="folder holding the scene (instead of --git)")
    ap.add_argument("--xml", required=True, help="scene file, relative to the mirror/folder")
    ap.add_argument("--scale", type=float, default=1.0, help="multiply positions (e.g. 0.01 for centimetres)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--frames", type=int, default=12, help="cameras in transforms.json: a sweep around the scene's sensor")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--sweep", type=float, default=40.0, help="total yaw of the sweep, degrees")
    ap.add_argument("--test-frames", type=int, default=0, help="held-out cameras (transforms_test.json) between the training ones")
    ap.add_argument("--materials", choices=["source", "varied", "bsdf"], default="source",
                    help="per-object roughness/specular (and albedo where the source has a texture): uniform, drawn per "
                         "object, or mapped from each shape's BSDF")
    ap.add_argument("--seed", type=int, default=1, help="with --materials varied")
    args = ap.parse_args()
    if args.frames < 1 or args.test_frames < 0:
        sys.exit("--frames must be >= 1 and --test-frames >= 0")
    if args.test_frames > max(args.frames - 1, 0):
        sys.exit(f"--test-frames {args.test_frames}: held-out cameras go between training ones, so at most --frames - 1 = {args.frames - 1}")
    src = Source(args.git, args.root)
    xml = src.read(args.xml)
    if xml is None:
        sys.exit(f"{args.xml}: not found")
    root = ET.fromstring(xml)
    base = os.path.dirname(args.xml)
    bsdfs = {b.attrib["id"]: b for b in root.iter("bsdf") if "id" in b.attrib}
    all_pos, all_nrm, all_tri, all_obj = [], [], [], []
    objects, missing, skipped, nv = [], [], [], 0
    any_normals = False
    cameras = []
    for s in root.iter("sensor"):
        t = s.find("transform")
        fov = s.find("float[@name='fov']")
        if t is not None:
            cameras.append({"to_world": parse_transform(t).tolist(), "fov": float(fov.attrib["value"]) if fov is not None else 60.0})
    for shape in root.iter("shape"):
        kind = shape.attrib.get("type")
        fn = shape.find("string[@name='filename']")
        if kind == "rectangle":  # Mitsuba's [-1,1]^2 at z = 0, normal +z
            path = f"rectangle#{sum(1 for o in objects)}"
        elif kind not in ("obj", "ply", "serialized") or fn is None:
            continue
        else:
            path = os.path.join(base, fn.attrib["value"])
        bsdf = shape.find("bsdf")
        if bsdf is None:
            bsdf = shape.find("ref")
        if transparent(bsdf, bsdfs):
            skipped.append(path)
            continue
        data = b"" if kind == "rectangle" else src.read(path)
        if data is None:
            missing.append(path)
            continue
        try:
            if kind == "rectangle":
                pos = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float64)
                nrm, tri = None, np.array([[0, 1, 2], [0, 2, 3]], np.int64)
            elif kind == "obj":
                pos, nrm, tri = read_obj(data)
            elif kind == "ply":
                pos, nrm, tri = read_ply(data)
            else:
                si = shape.find("integer[@name='shapeIndex']")
                pos, nrm, tri = read_serialized(data, int(si.attrib["value"]) if si is not None else 0)
        except Exception as e:  # noqa: BLE001 - one clear line per unreadable shape
            missing.append(f"{path} (unreadable: {e})")
            continue
        if len(tri) == 0:
            continue
        t = shape.find("transform")
        m = parse_transform(t) if t is not None else np.eye(4)
        if np.linalg.det(m[:3, :3]) < 0:  # a mirroring transform flips the winding; keep the front side
            tri = tri[:, ::-1].copy()
        fn_el = shape.find("boolean[@name='faceNormals']")
        if fn_el is not None and fn_el.attrib.get("value") == "true":
            nrm = None  # flat shading, as the source asks
        pos = (pos @ m[:3, :3].T + m[:3, 3]) * args.scale
        if nrm is not None:
            nrm = nrm @ np.linalg.inv(m[:3, :3])  # normals by the inverse transpose
            any_normals = True
        oid = len(objects)
        em = shape.find("emitter")
        radiance = None
        if em is not None:
            r = em.find("*[@name='radiance']")
            radiance = floats(r.attrib["value"]) if r is not None else [1.0, 1.0, 1.0]
            radiance = radiance * 3 if len(radiance) == 1 else radiance
        name = shape.attrib.get("id") or os.path.splitext(os.path.basename(path))[0]
        alb_m, rough_m, spec_m, bkind = bsdf_material(bsdf, bsdfs, src, base)
        ref_id = bsdf.attrib.get("id") if bsdf is not None and bsdf.tag == "ref" else None
        if ref_id:
            name = f"{name}_{ref_id}"
        if kind == "rectangle" and radiance:
            name = f"{name}_window_emitter"
        albedo = reflectance(bsdf, bsdfs)
        if args.materials == "bsdf":
            albedo = albedo if bkind not in ("conductor", "roughconductor", "dielectric", "roughdielectric") else alb_m
            albedo = albedo or texture_mean(inner_bsdf(bsdf, bsdfs), src, base)
        objects.append({"id": oid, "name": name, "albedo": albedo, "emission": radiance,
                        "roughness": rough_m, "specular": spec_m, "bsdf": bkind})
        all_pos.append(pos)
        all_nrm.append(nrm)
        all_tri.append(tri + nv)
        all_obj.append(np.full(len(tri), oid, np.int32))
        nv += len(pos)
    if not objects:
        sys.exit(f"{args.xml}: no readable mesh shapes")
    pos = np.concatenate(all_pos).astype(np.float32)
    tri = np.concatenate(all_tri).astype(np.int32)
    obj = np.concatenate(all_obj)
    os.makedirs(args.out, exist_ok=True)
    with open(os.path.join(args.out, "mesh.ply"), "wb") as f:
        props = "property float x\nproperty float y\nproperty float z\n"
        if any_normals:
            props += "property float nx\nproperty float ny\nproperty float nz\n"
        f.write((f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pos)}\n{props}"
                 f"element face {len(tri)}\nproperty list uchar int vertex_indices\nproperty int object_id\nend_header\n").encode())
        if any_normals:
            nrm = np.concatenate([n if n is not None else np.zeros((len(p), 3)) for n, p in zip(all_nrm, all_pos)]).astype(np.float32)
            f.write(np.concatenate([pos, nrm], 1).astype("<f4").tobytes())
        else:
            f.write(pos.astype("<f4").tobytes())
        rec = np.zeros(len(tri), dtype=[("n", "u1"), ("i", "<i4", 3), ("o", "<i4")])
        rec["n"], rec["i"], rec["o"] = 3, tri, obj
        f.write(rec.tobytes())
    with open(os.path.join(args.out, "materials_source.json"), "w") as f:
        json.dump([{k: o[k] for k in ("id", "name", "bsdf", "albedo", "roughness", "specular", "emission")} for o in objects], f, indent=1)
    with open(os.path.join(args.out, "objects.json"), "w") as f:
        json.dump({"objects": [{"id": o["id"], "name": o["name"]} for o in objects]}, f, indent=1)
    scene = {"mesh": "mesh.ply", "model": "principled-v1", "objects": []}
    for o, (albedo, roughness, specular) in zip(objects, object_materials(objects, args)):
        e = {"id": o["id"], "name": o["name"], "albedo": albedo, "roughness": roughness, "specular": specular}
        if o["emission"]:
            e["emission"] = o["emission"]
        scene["objects"].append(e)
    with open(os.path.join(args.out, "scene.json"), "w") as f:
        json.dump(scene, f, indent=1)
    lo, hi = pos.min(0), pos.max(0)
    info = {"source": args.xml, "triangles": int(len(tri)), "vertices": int(len(pos)), "objects": len(objects),
            "emitters": sum(1 for o in objects if o["emission"]), "bounds": [lo.tolist(), hi.tolist()],
            "transparent_skipped": skipped, "sensors": [{"to_world": scaled_translation(c["to_world"], args.scale), "fov": c["fov"]} for c in cameras], "missing": missing}
    with open(os.path.join(args.out, "source.json"), "w") as f:
        json.dump(info, f, indent=1)
    if info["sensors"]:
        write_cameras(args, info["sensors"][0])
    print(f"{args.xml}: {len(tri)} triangles, {len(objects)} objects, {info['emitters']} emitters, "
          f"bounds {np.round(lo, 2).tolist()} .. {np.round(hi, 2).tolist()}, {len(missing)} shapes missing, "
          f"{len(skipped)} transparent shapes left out")
    for m in missing:
        print(f"  missing: {m}")


if __name__ == "__main__":
    main()
