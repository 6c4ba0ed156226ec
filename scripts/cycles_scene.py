#!/usr/bin/env python3
"""Writes the Cycles comparison scene (scripts/cycles_compare.sh): a closed 4 x 2.7 x 3.5 m room
(y up) with objects spanning roughness 0.1-0.9 and specular 0-1, one ceiling area light, constant
albedos; mesh.ply (ascii, object_id per face, winding = front side), scene.json, transforms.json.
Usage: cycles_scene.py OUT_DIR [--model principled-v1|gltf] [--width 160 --height 120]"""
import argparse, json, math, os

# id, name, albedo, roughness, specular, emission (radiance, front side)
OBJECTS = [
    (0, "floor", (0.45, 0.35, 0.25), 0.35, 0.5, None),
    (1, "walls", (0.80, 0.78, 0.72), 0.9, 0.5, None),
    (2, "ceiling", (0.85, 0.85, 0.85), 0.8, 0.3, None),
    (3, "light", (0.80, 0.80, 0.80), 0.9, 0.0, (12.0, 11.0, 9.5)),
    (4, "vase", (0.15, 0.25, 0.65), 0.1, 0.6, None),
    (5, "table", (0.35, 0.22, 0.12), 0.25, 0.5, None),
    (6, "cabinet", (0.20, 0.35, 0.30), 0.8, 1.0, None),
    (7, "rug", (0.60, 0.20, 0.18), 0.9, 0.0, None),
    (8, "cube", (0.75, 0.70, 0.25), 0.5, 0.25, None),
    (9, "panel", (0.05, 0.05, 0.05), 0.15, 1.0, None),
]
ROOM = (4.0, 2.7, 3.5)


def sub(a, b): return tuple(x - y for x, y in zip(a, b))
def add(a, b): return tuple(x + y for x, y in zip(a, b))
def mul(a, s): return tuple(x * s for x in a)
def dot(a, b): return sum(x * y for x, y in zip(a, b))
def cross(a, b): return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
def norm(a): return mul(a, 1 / math.sqrt(dot(a, a)))


class Mesh:
    def __init__(self):
        self.v, self.f = [], []

    def tri(self, obj, a, b, c, facing):
        """Triangle whose winding normal points along `facing`."""
        if dot(cross(sub(b, a), sub(c, a)), facing) < 0: b, c = c, b
        i = len(self.v)
        self.v += [a, b, c]
        self.f.append((i, i + 1, i + 2, obj))

    def quad(self, obj, p, u, v, facing, n=1):
        for i in range(n):
            for j in range(n):
                a = add(p, add(mul(u, i / n), mul(v, j / n)))
                b, c, d = add(a, mul(u, 1 / n)), add(a, add(mul(u, 1 / n), mul(v, 1 / n))), add(a, mul(v, 1 / n))
                self.tri(obj, a, b, c, facing)
                self.tri(obj, a, c, d, facing)

    def box(self, obj, lo, hi):
        X, Y, Z = (hi[0] - lo[0], 0, 0), (0, hi[1] - lo[1], 0), (0, 0, hi[2] - lo[2])
        for p, u, v, n in [(lo, Z, X, (0, -1, 0)), (add(lo, Y), Z, X, (0, 1, 0)), (lo, Y, Z, (-1, 0, 0)),
                           (add(lo, X), Y, Z, (1, 0, 0)), (lo, X, Y, (0, 0, -1)), (add(lo, Z), X, Y, (0, 0, 1))]:
            self.quad(obj, p, u, v, n)

    def sphere(self, obj, c, r, seg=48):
        def pt(i, j):
            th, ph = math.pi * j / (seg // 2), 2 * math.pi * i / seg
            return add(c, (r * math.sin(th) * math.cos(ph), r * math.cos(th), r * math.sin(th) * math.sin(ph)))
        for i in range(seg):
            for j in range(seg // 2):
                a, b, cc, d = pt(i, j), pt(i + 1, j), pt(i + 1, j + 1), pt(i, j + 1)
                mid = mul(add(a, cc), 0.5)
                out = sub(mid, c)
                if j > 0: self.tri(obj, a, b, cc, out)
                if j < seg // 2 - 1: self.tri(obj, a, cc, d, out)


def build():
    m = Mesh()
    W, H, D = ROOM
    X, Y, Z = (W, 0, 0), (0, H, 0), (0, 0, D)
    m.quad(0, (0, 0, 0), X, Z, (0, 1, 0), 4)                 # floor
    m.quad(2, (0, H, 0), X, Z, (0, -1, 0), 4)                # ceiling
    m.quad(1, (0, 0, 0), X, Y, (0, 0, 1), 4)                 # walls, facing inwards
    m.quad(1, (0, 0, D), X, Y, (0, 0, -1), 4)
    m.quad(1, (0, 0, 0), Z, Y, (1, 0, 0), 4)
    m.quad(1, (W, 0, 0), Z, Y, (-1, 0, 0), 4)
    m.quad(3, (1.6, H - 0.01, 1.45), (0.8, 0, 0), (0, 0, 0.6), (0, -1, 0))  # light, facing down
    m.box(5, (1.2, 0.70, 1.2), (2.6, 0.75, 2.1))               # table top and legs
    for lx, lz in [(1.25, 1.25), (2.5, 1.25), (1.25, 2.0), (2.5, 2.0)]:
        m.box(5, (lx, 0, lz), (lx + 0.05, 0.70, lz + 0.05))
    m.sphere(4, (1.9, 0.95, 1.65), 0.2)                      # vase
    m.box(6, (3.3, 0, 0.2), (3.9, 1.1, 1.2))                 # cabinet
    m.quad(7, (1.0, 0.005, 2.3), (0, 0, 1.0), (1.8, 0, 0), (0, 1, 0))  # rug
    m.box(8, (0.3, 0, 2.6), (0.8, 0.5, 3.1))                 # cube
    m.quad(9, (0.01, 1.0, 1.0), (0, 0, 1.2), (0, 0.8, 0), (1, 0, 0))   # glossy panel on the x = 0 wall
    return m


def look_at(eye, target):
    f = norm(sub(target, eye))
    r = norm(cross(f, (0, 1, 0)))
    u = cross(r, f)
    b = mul(f, -1)
    return [[r[0], u[0], b[0], eye[0]], [r[1], u[1], b[1], eye[1]], [r[2], u[2], b[2], eye[2]], [0, 0, 0, 1]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--model", default="principled-v1")
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    m = build()
    with open(os.path.join(a.out, "mesh.ply"), "w") as f:
        f.write("ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n" % len(m.v))
        f.write("element face %d\nproperty list uchar int vertex_indices\nproperty int object_id\nend_header\n" % len(m.f))
        for v in m.v: f.write("%.6f %.6f %.6f\n" % v)
        for t in m.f: f.write("3 %d %d %d %d\n" % t)
    objects = []
    for oid, name, albedo, r, s, e in OBJECTS:
        objects.append({"id": oid, "name": name, "albedo": list(albedo), "roughness": r, "specular": s,
                        "emission": list(e) if e else [0, 0, 0]})
    with open(os.path.join(a.out, "scene.json"), "w") as f:
        json.dump({"mesh": "mesh.ply", "model": a.model, "objects": objects}, f, indent=1)
    fl = 0.5 * a.width / math.tan(math.radians(75) / 2)
    views = [((3.7, 1.6, 3.2), (1.6, 0.6, 1.2)), ((0.4, 2.0, 0.3), (2.6, 0.5, 2.4)), ((3.8, 0.9, 1.7), (0.0, 1.0, 2.0)),
             ((3.2, 0.6, 3.3), (1.4, 2.7, 1.0))]
    frames = [{"file_path": "images/view_%d.exr" % i, "transform_matrix": look_at(e, t)} for i, (e, t) in enumerate(views)]
    with open(os.path.join(a.out, "transforms.json"), "w") as f:
        json.dump({"camera_model": "PINHOLE", "fl_x": fl, "fl_y": fl, "cx": a.width / 2, "cy": a.height / 2,
                   "w": a.width, "h": a.height, "frames": frames}, f, indent=1)


if __name__ == "__main__":
    main()
