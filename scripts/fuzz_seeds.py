#!/usr/bin/env python3
"""Writes the seed corpus tests/data/fuzz/<reader>/seed_* from relume's own outputs, cut small
(a few KB per reader). Usage, from a build with build/relume:
  relume synth --scene cornell --out S/cap --frames 3 --test-frames 1 --width 16 --height 12 --spp 1 --max-depth 2
  relume prepare S/cap --out S/work --res 64 --gutter-res 64 --tile 16
  echo '{"stop_after_iterations": 2, "checkpoint_every": 1}' > S/fit.json && relume fit S/work --config S/fit.json
  scripts/fuzz_seeds.py S
`scripts/fuzz_seeds.py --hand-made` writes only the seeds made by hand (COLMAP models, the checkpoint's
records), which need no build.
Inputs the fuzzer found (crash-*, timeout-*, oom-*) live next to the seeds and are never rewritten."""
import json, os, shutil, struct, sys

src, out = sys.argv[1], os.path.join(os.path.dirname(__file__), "..", "tests", "data", "fuzz")


def put(reader, name, data):
    os.makedirs(os.path.join(out, reader), exist_ok=True)
    with open(os.path.join(out, reader, "seed_" + name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


# A COLMAP model is two files; the harness splits its input into cameras and images at a 4-byte
# little-endian length prefix (fuzz/readers.cpp). Images a.png ... f.png and sub/g.png exist in the
# scratch folder, so the seeds read without error.
def colmap_model(cameras, images):
    return struct.pack("<I", len(cameras)) + cameras + images


def colmap_seeds():
    cameras = ("# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
               "1 PINHOLE 16 12 20 21 8 6\n")
    images = ("# Image list with two lines of data per image:\n"
              "1 0.99500416527802582 0.099833416646828155 0 0 0.5 -0.25 3 1 a.png\n"
              "1.5 2.5 -1 3.25 4.75 7\n"
              "2 1 0 0 0 0 0 2 1 b.png\n\n")
    put("colmap-text", "pinhole", colmap_model(cameras.encode(), images.encode()))
    cameras = ("1 SIMPLE_PINHOLE 16 12 20 8 6\n2 SIMPLE_RADIAL 16 12 20 8 6 -0.1\n\n3 RADIAL 16 12 20 8 6 -0.1 0.01\n"
               "4 OPENCV 16 12 20 21 8 6 -0.1 0.01 0.001 -0.002\n"
               "5 FULL_OPENCV 16 12 20 21 8 6 -0.1 0.01 0.001 -0.002 0.003 0 0 0\n")
    images = "".join(f"{i} 0.5 0.5 0.5 0.5 0 0 {i} {i} {'abcde'[i - 1]}.png\n\n" for i in range(1, 6))
    images += "6 1 0 0 0 0 0 1 4 f.png\n\n7 1 0 0 0 0 0 1 2 sub/g.png\n"
    put("colmap-text", "models", colmap_model(cameras.encode(), images.encode()))

    def camera(cid, model, w, h, params):
        return struct.pack("<iiQQ", cid, model, w, h) + struct.pack(f"<{len(params)}d", *params)

    def image(iid, q, t, cid, name, points):
        data = struct.pack("<I7dI", iid, *q, *t, cid) + name + b"\0" + struct.pack("<Q", len(points))
        return data + b"".join(struct.pack("<ddq", x, y, p) for x, y, p in points)

    cams = struct.pack("<Q", 1) + camera(1, 1, 16, 12, [20, 21, 8, 6])
    ims = struct.pack("<Q", 2) + image(1, [1, 0, 0, 0], [0, 0, 2], 1, b"a.png", []) + image(
        2, [0.99500416527802582, 0.099833416646828155, 0, 0], [0.5, -0.25, 3], 1, b"b.png", [(1.5, 2.5, -1), (3, 4, 7)])
    put("colmap-binary", "pinhole", colmap_model(cams, ims))
    cams = struct.pack("<Q", 3) + camera(1, 0, 16, 12, [20, 8, 6]) + camera(2, 3, 16, 12, [20, 8, 6, -0.1, 0.01]) + \
        camera(3, 4, 16, 12, [20, 21, 8, 6, -0.1, 0.01, 0.001, -0.002])
    ims = struct.pack("<Q", 3) + b"".join(image(i, [0.5, 0.5, 0.5, 0.5], [0, 0, i], i, b"abc"[i - 1:i] + b".png", [])
                                          for i in range(1, 4))
    put("colmap-binary", "models", colmap_model(cams, ims))


# A checkpoint holding what `fit --resume` reads after the parameters, for two objects (the second
# with a roughness bound and a sharp branch), two texels (the second beyond albedo 1) and a time
# budget's plan of three stages. The harness sizes the records from `emitter`, `albedo` and
# `budget.lengths`.
def checkpoint_records_seed():
    arrays = {
        "albedo": struct.pack("<6f", 0.5, 0.5, 0.5, 0.9, 0.9, 0.9),
        "albedo.standard_error": struct.pack("<6f", 0.01, 0.01, 0.01, -1, 0.02, 0.02),
        "albedo.beyond_one_count": struct.pack("<Q", 1),
        "albedo.beyond_one": struct.pack("<I", 1),
        "albedo.beyond_one_albedo": struct.pack("<3f", 1.2, 1.1, 1.3),
        "emitter": bytes([1, 0]), "out_of_model": bytes([0, 0]), "highlight": bytes([0, 0]),
        "refit_emission": bytes([0]), "clipped_lights": bytes([0]), "clipped_scale_moving": bytes([0]),
        "highlight_pairs": struct.pack("<2Q", 0, 40), "highlight_contrast": struct.pack("<2d", 0, 0.03),
        "roughness_at_least": struct.pack("<2f", -1, 0.6), "sharp_below": struct.pack("<2f", -1, 0.15),
        "observed.sum": struct.pack("<2d", 80.5, 12.25), "observed.count": struct.pack("<2Q", 7, 49),
        "budget.lengths": struct.pack("<3i", 200, 1000, 100), "budget.planned_at": struct.pack("<3i", 11, 31, -1),
        "budget.numbers": struct.pack("<4d", 42.5, 0.5, 1.0, 2.0), "budget.counts": struct.pack("<3i", 1, 10, 2),
    }
    names = sorted(arrays)
    text = json.dumps({"meta": {"light_decisions": [{"object": 0, "verdict": "light"}]},
                       "arrays": [[n, len(arrays[n])] for n in names]}, separators=(",", ":")).encode()
    body = b"".join(arrays[n] for n in names)
    put("checkpoint", "records.bin", b"RLMCKP01" + struct.pack("<Q", len(text)) + text + body)


if sys.argv[1:] == ["--hand-made"]:
    colmap_seeds()
    checkpoint_records_seed()
    sys.exit(0)


def read(*path):
    with open(os.path.join(src, *path), "rb") as f:
        return f.read()


def compact(j):
    return json.dumps(j, separators=(",", ":"))


# Meshes: relume's binary PLY, an ascii polygon mesh, and the two inputs that once hung prepare/the reader.
put("ply", "cornell.ply", read("cap", "mesh.ply"))
ascii_header = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                "element face 2\nproperty list uchar int vertex_indices\nproperty int segment_id\nend_header\n")
put("ply", "ascii_quad.ply", ascii_header + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 7\n3 0 1 2 1\n")
put("ply", "coincident.ply", ascii_header + "0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 0\n3 0 1 2 0\n")
put("ply", "empty_element.ply", "ply\nformat binary_little_endian 1.0\nelement junk 18446744073709551615\nend_header\n")
obj = "o box\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\ng front\nf 1/1/1 2/2/1 3/3/1 4/1/1\ng back\nf -1 -2 -3\n"
put("obj", "groups.obj", obj)
put("obj", "repeated_vertex.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 2 3\nf 1 2 3\n")

# Capture files: cameras of synth, both objects.json forms.
transforms = json.loads(read("cap", "transforms.json"))
transforms["frames"] = transforms["frames"][:1]
put("transforms", "synth.json", compact(transforms))
put("transforms", "global_pinhole.json", compact({"camera_model": "PINHOLE", "fl_x": 20, "w": 16, "h": 12, "frames": [
    {"file_path": "a.png", "exposure": 2, "clip_high": 0.9, "transform_matrix": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]}]}))
put("objects", "list.json", compact(json.loads(read("cap", "objects.json"))))
put("objects", "map.json", compact({"0": "floor", "1": "wall"}))

# scene.json against the fuzz scratch folder: mesh.ply with objects 0 and 1 (uv), texture.exr.
scene = json.loads(read("cap", "gt", "scene.json"))
scene["albedo_texture"] = "texture.exr"
scene["objects"] = scene["objects"][:2]
put("scene", "cornell.json", compact(scene))
scene["objects"][1]["emission_texture"] = "texture.exr"
scene["objects"][1]["emission_window"] = [0, 0, 2, 2]
del scene["albedo_texture"]
put("scene", "emission_texture.json", compact(scene))

# Images: a float EXR frame, 8-bit sRGB PNGs.
put("image", "frame.exr", read("cap", "images", "frame_0000.exr"))
put("image", "coverage.png", read("work", "coverage.png"))

# Files of earlier runs: frame cache, visibility index, and a checkpoint with its arrays cut to 16 bytes.
put("frames", "prepare.bin", read("work", "frames.bin"))
put("frames", "header_only.bin", read("work", "frames.bin")[:16])
put("visibility", "prepare.bin", read("work", "visibility.bin"))
put("visibility", "header_only.bin", read("work", "visibility.bin")[:24])
ck = read("work", "checkpoint.bin")
(length,) = struct.unpack("<Q", ck[8:16])
header = json.loads(ck[16:16 + length])
header["arrays"] = [[name, min(n, 16)] for name, n in header["arrays"]]
header["meta"] = {k: header["meta"][k] for k in list(header["meta"])[:4]}
text = compact(header).encode()
put("checkpoint", "fit.bin", ck[:8] + struct.pack("<Q", len(text)) + text + bytes(sum(n for _, n in header["arrays"])))
put("checkpoint", "empty.bin", ck[:8] + struct.pack("<Q", 24) + b'{"arrays":[],"meta":{}} ')
colmap_seeds()
checkpoint_records_seed()
