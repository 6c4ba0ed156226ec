"""Blender 3.4 side of scripts/cycles_compare.sh (run with `blender -b --factory-startup --python
cycles_compare.py -- MODE ...`).

render SCENE_DIR OUT_DIR --spp N --seed S [--bounces 8 --diffuse-bounces 8 --glossy-bounces 8
       --distribution GGX|MULTI_GGX --blur-glossy 0 --clamp-indirect 0 --filter-width 1.5]
       [--gltf FILE.glb [--front-emission]] [--transforms T.json]
  Builds the relume scene (scene.json + ascii mesh.ply + transforms.json) in Cycles: one
  Principled BSDF (v1: metallic 0, specular tint 0, sheen/clearcoat/subsurface/transmission 0) per
  object, plus an Emission shader of the object's radiance on the front side only (relume's
  emitters are one-sided); black world; cameras from transforms.json (OpenGL axes = Blender's).
  Writes OUT_DIR/view_K.exr (linear RGB), OUT_DIR/view_K_index.exr (object id + 1) and
  OUT_DIR/view_K_albedo.exr (Cycles' Diffuse Color pass: the albedo pass relume eval can compare with).
  --gltf imports `relume export`'s .glb with Blender's glTF importer instead (materials as the
  importer maps them, nothing fixed up; scripts/gltf_blender_check.sh); --front-emission then
  makes emission one-sided, as relume's.

compare SCENE_DIR RELUME_A RELUME_B CYCLES_A CYCLES_B
  Per object: mean radiance over pixels whose 3x3 neighbourhood is that object in both relume's
  object AOV and Cycles' index pass (so neither pixel filter reaches another object), pooled over
  views; A and B are independent renders (other seeds), so the standard error of each mean is
  sqrt(sum (A - B)^2) / (2 n). Prints relume / Cycles per object with its standard error.
"""
import argparse, json, math, os, sys

import bpy


def args_after_dashes():
    return sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def read_ascii_ply(path):
    with open(path) as f:
        lines = f.read().split("\n")
    nv = nf = 0
    i = 0
    while lines[i] != "end_header":
        t = lines[i].split()
        if t[:2] == ["element", "vertex"]: nv = int(t[2])
        if t[:2] == ["element", "face"]: nf = int(t[2])
        i += 1
    i += 1
    verts = [tuple(map(float, lines[i + k].split()[:3])) for k in range(nv)]
    faces = []
    for k in range(nf):
        t = list(map(int, lines[i + nv + k].split()))
        faces.append((t[1:1 + t[0]], t[1 + t[0]]))
    return verts, faces


def material(o, distribution):
    m = bpy.data.materials.new(o["name"])
    m.use_nodes = True
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    p.distribution = distribution
    p.inputs["Base Color"].default_value = (*o["albedo"], 1.0)
    p.inputs["Metallic"].default_value = 0.0
    p.inputs["Specular"].default_value = o["specular"]
    p.inputs["Specular Tint"].default_value = 0.0
    p.inputs["Roughness"].default_value = o["roughness"]
    for name in ("Sheen", "Clearcoat", "Subsurface", "Transmission"):
        p.inputs[name].default_value = 0.0
    p.inputs["Emission Strength"].default_value = 0.0
    if max(o["emission"]) > 0:
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = (*o["emission"], 1.0)
        geo = nt.nodes.new("ShaderNodeNewGeometry")
        front = nt.nodes.new("ShaderNodeMath")
        front.operation = "SUBTRACT"
        front.inputs[0].default_value = 1.0
        nt.links.new(geo.outputs["Backfacing"], front.inputs[1])
        nt.links.new(front.outputs[0], em.inputs["Strength"])
        add = nt.nodes.new("ShaderNodeAddShader")
        nt.links.new(p.outputs["BSDF"], add.inputs[0])
        nt.links.new(em.outputs["Emission"], add.inputs[1])
        nt.links.new(add.outputs["Shader"], nt.nodes["Material Output"].inputs["Surface"])
    return m


def build_scene(a, sc):
    """The relume scene rebuilt node by node from scene.json + mesh.ply (constant albedos)."""
    scene_json = json.load(open(os.path.join(a.scene, "scene.json")))
    verts, faces = read_ascii_ply(os.path.join(a.scene, scene_json["mesh"]))
    for o in scene_json["objects"]:
        fs = [f for f, oid in faces if oid == o["id"]]
        used = sorted({v for f in fs for v in f})
        remap = {v: k for k, v in enumerate(used)}
        me = bpy.data.meshes.new(o["name"])
        me.from_pydata([verts[v] for v in used], [], [[remap[v] for v in f] for f in fs])
        me.update()
        me.materials.append(material(o, a.distribution))
        ob = bpy.data.objects.new(o["name"], me)
        ob.pass_index = o["id"] + 1
        sc.collection.objects.link(ob)


def import_gltf(a):
    """`relume export --gltf` as Blender's own importer reads it, untouched; returns the rotation
    it applied (glTF y-up to Blender z-up), which the cameras need too."""
    from mathutils import Matrix
    import numpy
    # Debian bookworm pairs Blender 3.4's importer (np.bool) with numpy 1.24, which removed the
    # alias: the importer fails on any mesh without this shim (the .glb is not the cause).
    if not hasattr(numpy, "bool"):
        numpy.bool = bool
    bpy.ops.import_scene.gltf(filepath=a.gltf)
    for ob in bpy.data.objects:
        if "relume_object_id" in ob:  # node extras become custom properties
            ob.pass_index = int(ob["relume_object_id"]) + 1
    if a.front_emission:
        for m in bpy.data.materials:
            front_side_emission(m)
    return Matrix.Rotation(math.pi / 2, 4, "X")


def front_side_emission(m):
    """The one fix-up an imported relume scene needs: Blender emits on both sides of a face,
    relume (and the glTF export's intent) on the front side only. Strength *= 1 - Backfacing."""
    if not m.use_nodes:
        return
    nt = m.node_tree
    p = next((n for n in nt.nodes if n.type == "BSDF_PRINCIPLED"), None)
    if p is None:
        return
    color, strength = p.inputs["Emission"], p.inputs["Emission Strength"]
    if strength.is_linked or (not color.is_linked and max(color.default_value[:3]) == 0):
        return
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    front = nt.nodes.new("ShaderNodeMath")
    front.operation = "SUBTRACT"
    front.inputs[0].default_value = 1.0
    nt.links.new(geo.outputs["Backfacing"], front.inputs[1])
    scaled = nt.nodes.new("ShaderNodeMath")
    scaled.operation = "MULTIPLY"
    scaled.inputs[1].default_value = strength.default_value
    nt.links.new(front.outputs[0], scaled.inputs[0])
    nt.links.new(scaled.outputs[0], strength)


def render(a):
    from mathutils import Matrix
    transforms = json.load(open(a.transforms or os.path.join(a.scene, "transforms.json")))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    world_to_blender = Matrix.Identity(4)
    if a.gltf:
        world_to_blender = import_gltf(a)
    else:
        build_scene(a, sc)
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    sc.world = world
    sc.render.engine = "CYCLES"
    c = sc.cycles
    c.device = "CPU"
    c.samples = a.spp
    c.seed = a.seed
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = a.bounces
    c.diffuse_bounces = a.diffuse_bounces
    c.glossy_bounces = a.glossy_bounces
    c.transmission_bounces = a.bounces
    c.transparent_max_bounces = a.bounces
    c.volume_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = a.clamp_indirect
    c.blur_glossy = a.blur_glossy
    c.light_sampling_threshold = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    c.pixel_filter_type = "BLACKMAN_HARRIS"  # Cycles' default; cycles_capture.sh declares it in the capture
    c.filter_width = a.filter_width
    sc.render.threads_mode = "FIXED"
    sc.render.threads = a.threads
    sc.render.resolution_percentage = 100
    sc.render.film_transparent = False
    sc.view_settings.view_transform = "Standard"
    sc.view_layers[0].use_pass_object_index = True
    sc.view_layers[0].use_pass_diffuse_color = True  # the albedo pass relume eval compares albedo with
    sc.use_nodes = True
    nt = sc.node_tree
    layers = nt.nodes["Render Layers"]
    out = nt.nodes.new("CompositorNodeOutputFile")
    out.base_path = a.out
    out.format.file_format = "OPEN_EXR"
    out.format.color_depth = "32"
    out.format.exr_codec = "ZIP"
    out.file_slots.clear()
    cam_data = bpy.data.cameras.new("cam")
    cam_data.sensor_fit = "HORIZONTAL"
    cam_data.sensor_width = 36.0
    cam = bpy.data.objects.new("cam", cam_data)
    sc.collection.objects.link(cam)
    sc.camera = cam
    for k, fr in enumerate(transforms["frames"]):
        stem = os.path.splitext(os.path.basename(fr["file_path"]))[0]
        intrinsic = lambda key: float(fr.get(key, transforms.get(key)))  # per frame or top-level
        sc.render.resolution_x, sc.render.resolution_y = int(intrinsic("w")), int(intrinsic("h"))
        cam_data.lens = intrinsic("fl_x") * 36.0 / intrinsic("w")
        cam.matrix_world = world_to_blender @ Matrix(fr["transform_matrix"])
        out.file_slots.clear()
        out.file_slots.new(stem + "_#")
        out.file_slots.new(stem + "_index_#")
        out.file_slots.new(stem + "_albedo_#")
        nt.links.new(layers.outputs["Image"], out.inputs[0])
        nt.links.new(layers.outputs["IndexOB"], out.inputs[1])
        nt.links.new(layers.outputs["DiffCol"], out.inputs[2])
        sc.frame_set(1)
        bpy.ops.render.render(write_still=False)
        for suffix in ("", "_index", "_albedo"):
            os.replace(os.path.join(a.out, "%s%s_1.exr" % (stem, suffix)), os.path.join(a.out, "%s%s.exr" % (stem, suffix)))


def load(path):
    img = bpy.data.images.load(path)
    img.colorspace_settings.name = "Non-Color"
    w, h = img.size
    px = list(img.pixels)
    ch = img.channels
    bpy.data.images.remove(img)
    return w, h, [px[i * ch:i * ch + 3] for i in range(w * h)]


def compare(a):
    scene_json = json.load(open(os.path.join(a.scene, "scene.json")))
    transforms = json.load(open(a.transforms or os.path.join(a.scene, "transforms.json")))
    names = {o["id"]: o["name"] for o in scene_json["objects"]}
    acc = {}  # id -> [n, sum relume, sum cycles, sum (dRelume)^2, sum (dCycles)^2]
    for fr in transforms["frames"]:
        stem = os.path.splitext(os.path.basename(fr["file_path"]))[0]
        w, h, ra = load(os.path.join(a.relume_a, stem + ".exr"))
        _, _, rb = load(os.path.join(a.relume_b, stem + ".exr"))
        _, _, ca = load(os.path.join(a.cycles_a, stem + ".exr"))
        _, _, cb = load(os.path.join(a.cycles_b, stem + ".exr"))
        _, _, robj = load(os.path.join(a.relume_a, stem + "_object.exr"))
        _, _, cidx = load(os.path.join(a.cycles_a, stem + "_index.exr"))
        rid = [int(round(p[0])) for p in robj]
        cid = [int(round(p[0])) - 1 for p in cidx]
        for y in range(1, h - 1):
            for x in range(1, w - 1):
                i = y * w + x
                oid = rid[i]
                if oid < 0 or any(rid[j] != oid or cid[j] != oid for j in
                                  (i + dy * w + dx for dy in (-1, 0, 1) for dx in (-1, 0, 1))):
                    continue
                lr = [(ra[i][c] + rb[i][c]) / 2 for c in range(3)]
                lc = [(ca[i][c] + cb[i][c]) / 2 for c in range(3)]
                e = acc.setdefault(oid, [0, [0.0] * 3, [0.0] * 3, [0.0] * 3, [0.0] * 3])
                e[0] += 1
                for c in range(3):
                    e[1][c] += lr[c]
                    e[2][c] += lc[c]
                    e[3][c] += (ra[i][c] - rb[i][c]) ** 2
                    e[4][c] += (ca[i][c] - cb[i][c]) ** 2
    print("%-9s %6s %10s %10s %8s %8s %8s %8s" % ("object", "pixels", "relume", "cycles", "ratio", "se", "r/c red", "r/c blue"))
    for oid in sorted(acc):
        n, sr, scy, vr, vc = acc[oid]
        mr, mc = sum(sr) / (3 * n), sum(scy) / (3 * n)
        ser = math.sqrt(sum(vr) / 3) / (2 * n)  # approximately: channels pooled
        sec = math.sqrt(sum(vc) / 3) / (2 * n)
        if min(mr, mc, scy[0], scy[2]) <= 0:
            print("%-9s %6d %10.5f %10.5f (no light)" % (names[oid], n, mr, mc))
            continue
        ratio = mr / mc
        se = ratio * math.hypot(ser / mr, sec / mc)
        print("%-9s %6d %10.5f %10.5f %8.4f %8.4f %8.4f %8.4f" % (names[oid], n, mr, mc, ratio, se,
                                                                  sr[0] / scy[0], sr[2] / scy[2]))


def main():
    argv = args_after_dashes()
    mode = argv[0]
    ap = argparse.ArgumentParser(prog="cycles_compare.py " + mode)
    if mode == "render":
        ap.add_argument("scene")
        ap.add_argument("out")
        ap.add_argument("--spp", type=int, default=256)
        ap.add_argument("--seed", type=int, default=1)
        ap.add_argument("--bounces", type=int, default=8)
        ap.add_argument("--diffuse-bounces", type=int, default=8)
        ap.add_argument("--glossy-bounces", type=int, default=8)
        ap.add_argument("--distribution", default="GGX", choices=["GGX", "MULTI_GGX"])
        ap.add_argument("--blur-glossy", type=float, default=0.0)
        ap.add_argument("--clamp-indirect", type=float, default=0.0)
        ap.add_argument("--filter-width", type=float, default=1.5)
        ap.add_argument("--threads", type=int, default=2)
        ap.add_argument("--gltf", help="import this .glb (relume export) instead of building SCENE_DIR's scene.json")
        ap.add_argument("--transforms", help="cameras (default SCENE_DIR/transforms.json)")
        ap.add_argument("--front-emission", action="store_true", help="with --gltf: emit on the front side only, as relume")
        render(ap.parse_args(argv[1:]))
    elif mode == "compare":
        for k in ("scene", "relume_a", "relume_b", "cycles_a", "cycles_b"):
            ap.add_argument(k)
        ap.add_argument("--transforms", help="cameras (default SCENE_DIR/transforms.json)")
        compare(ap.parse_args(argv[1:]))
    else:
        sys.exit("cycles_compare.py: mode must be render or compare, not '%s'" % mode)


main()
