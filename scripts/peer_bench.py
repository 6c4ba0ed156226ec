#!/usr/bin/env python3
"""Mitsuba 3 side of scripts/peer_bench.sh (relume vs Mitsuba 3 prb, issue 12). Not part of the
tests; Mitsuba (pip install mitsuba, variant llvm_ad_rgb) is never a dependency of relume.

camera TRANSFORMS OUT_JSON --rays N
  One camera (the first frame of TRANSFORMS) re-sized to a square image of N pixels (same focal
  length in units of the width): the ray batch of one gradient iteration at 1 spp.

iter SCENE_XML TRANSFORMS REF_EXR --depth D [--repeats 2] [--seed 1]
  One gradient iteration, Mitsuba's way: prb integrator (max_depth = D + 1: relume's D scattering
  vertices plus the emitter segment; no Russian roulette), mi.render of the camera at 1 spp with the
  albedo texture and every area emitter's radiance attached to the AD graph, L2 loss against
  REF_EXR, dr.backward, gradients evaluated. The scene is perturbed first as relume's profile does
  (albedo 0.7 a + 0.1, emission x 0.8). One warm-up iteration (JIT tracing, kernel compilation or
  cache), then REPEATS timed ones. Prints one JSON line: seconds per timed iteration, VmRSS after
  loading (before any iteration), VmHWM at the end (peak RSS of this process).

fit SCENE_XML TRANSFORMS OUT_DIR --snapshots S1,S2,... [--depth 9] [--lr 0.05] [--lr-emission 0.5]
  Reconstruction: the albedo texture (bitmap on the export's uvs) and the radiance of every area
  emitter of the scene, optimised by Adam(mask_updates=True) on prb gradients of the L2 loss of
  1-spp renders of the training frames (one random frame per iteration, full resolution). The
  clock starts after the scene and frames are loaded; at each snapshot time (seconds) the state
  is written to OUT_DIR/t<k>/ (albedo.exr + scene.json for `relume eval`, clock paused meanwhile).

efficiency SCENE_XML TRANSFORMS RAYS_BIN --spp 4 --depth D [--repeats 3]
  Renderer efficiency, Mitsuba's: its `path` integrator (max_depth D + 1, no Russian roulette,
  llvm_ad_rgb, no AD) renders the camera at SPP, and its Embree traversal alone replays RAYS_BIN,
  the rays relume's render of the same camera, spp and depth traced (`relume profile --what render
  --scene --cameras --rays-out`): closest hits through ray_intersect_preliminary, shadow rays
  through ray_test. Best of REPEATS after a warm-up each (JIT). Prints one JSON line.

initscene GT_SCENE WORK OUT_DIR --res 512
  The starting point of the Mitsuba fit, as a relume scene.json on the work folder's atlas mesh
  (the uv space relume's fit and eval use): albedo 0.5 grey (res^2), roughness and specular 0.5 on
  every object (what relume's fit keeps with material_iterations 0), emission (1,1,1) on the
  ground truth's emitters, 0 elsewhere.

table OUT
  Collects OUT/*.json and the relume logs into the markdown of OUT/peer.md.
"""
import argparse, glob, json, math, os, re, statistics, sys, time

import numpy as np


def rss_mib(field):
    for line in open("/proc/self/status"):
        if line.startswith(field + ":"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def write_exr(path, rgb):
    import OpenEXR
    rgb = np.ascontiguousarray(rgb, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, {"RGB": rgb}) as f:
        f.write(path)


def mitsuba():
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    return mi


def sensor_dict(mi, fr, get, spp):
    w, h = int(get("w")), int(get("h"))
    c2w = np.array(fr["transform_matrix"], dtype=float) @ np.diag([-1.0, 1.0, -1.0, 1.0])
    fov = math.degrees(2 * math.atan(w / (2 * get("fl_x"))))
    return {
        "type": "perspective", "fov": fov, "fov_axis": "x", "to_world": mi.ScalarTransform4f(c2w.tolist()),
        "principal_point_offset_x": (get("cx") - w / 2) / w, "principal_point_offset_y": (get("cy") - h / 2) / h,
        "sampler": {"type": "independent", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb",
                 "sample_border": False},
    }


def frames(path):
    t = json.load(open(path))
    for fr in t["frames"]:
        yield fr, (lambda k, fr=fr: float(fr.get(k, t.get(k))))


def prb(mi, depth):
    return mi.load_dict({"type": "prb", "max_depth": depth + 1, "rr_depth": 1 << 20})


def opt_keys(mi, params):
    """The albedo texture (the one 3-channel bitmap tensor) and every area emitter's radiance."""
    tex = [k for k in params.keys() if k.endswith(".data") and len(params[k].shape) == 3 and params[k].shape[2] == 3]
    emit = [k for k in params.keys() if k.endswith("emitter.radiance.value")]
    if len(tex) != 1:
        sys.exit("peer_bench.py: expected one albedo bitmap in the scene, found %s" % tex)
    return tex[0], emit


def cmd_camera(a):
    t = json.load(open(a.transforms))
    fr = dict(t["frames"][0])
    for k in ("w", "h", "fl_x", "fl_y", "cx", "cy"):
        fr.setdefault(k, t.get(k))
    side = int(round(math.sqrt(a.rays)))
    s = side / float(fr["w"])
    fr.update({"w": side, "h": side, "fl_x": fr["fl_x"] * s, "fl_y": fr["fl_x"] * s, "cx": side / 2.0, "cy": side / 2.0,
               "file_path": "ref_%d.exr" % side})
    out = {k: v for k, v in t.items() if k not in ("frames", "w", "h", "fl_x", "fl_y", "cx", "cy")}
    out["frames"] = [fr]
    json.dump(out, open(a.out, "w"), indent=1)


def cmd_iter(a):
    mi = mitsuba()
    import drjit as dr
    scene = mi.load_file(a.scene_xml)
    fr, get = next(frames(a.transforms))
    sensor = mi.load_dict(sensor_dict(mi, fr, get, 1))
    ref = mi.TensorXf(np.array(mi.Bitmap(a.ref), dtype=np.float32)[:, :, :3])
    integrator = prb(mi, a.depth)
    params = mi.traverse(scene)
    ka, ke = opt_keys(mi, params)
    params[ka] = 0.7 * params[ka] + 0.1
    for k in ke:
        params[k] = params[k] * 0.8
    params.keep([ka] + ke)
    params.update()
    rss0 = rss_mib("VmRSS")
    secs = []
    for it in range(1 + a.repeats):
        t0 = time.perf_counter()
        for k in params.keys():
            dr.enable_grad(params[k])
        params.update()
        img = mi.render(scene, params, sensor=sensor, integrator=integrator, spp=1, seed=a.seed + it)
        loss = dr.mean(dr.square(img - ref), axis=None)
        dr.backward(loss)
        grads = [dr.grad(params[k]) for k in params.keys()]
        dr.eval(*grads)
        dr.sync_thread()
        secs.append(time.perf_counter() - t0)
        for k in params.keys():
            dr.disable_grad(params[k])
    nrays = int(get("w")) * int(get("h"))
    gsum = [float(np.abs(np.array(g)).sum()) for g in grads]  # sanity: the gradients are not zero
    print(json.dumps({"rays": nrays, "depth": a.depth, "warmup_s": secs[0], "seconds": secs[1:], "grad_abs_sum": gsum,
                      "rss_loaded_mib": rss0, "peak_rss_mib": rss_mib("VmHWM"), "params": [ka] + ke}))


def cmd_efficiency(a):
    mi = mitsuba()
    import drjit as dr
    scene = mi.load_file(a.scene_xml)
    fr, get = next(frames(a.transforms))
    sensor = mi.load_dict(sensor_dict(mi, fr, get, a.spp))
    integrator = mi.load_dict({"type": "path", "max_depth": a.depth + 1, "rr_depth": 1 << 20})

    def best(run):
        times = []
        for _ in range(1 + a.repeats):  # the first compiles (or loads) the kernels
            t0 = time.perf_counter()
            run()
            dr.sync_thread()
            times.append(time.perf_counter() - t0)
        return min(times[1:])

    def render():
        dr.eval(mi.render(scene, sensor=sensor, integrator=integrator, spp=a.spp, seed=1))

    rays = np.fromfile(a.rays, dtype="<f4").reshape(-1, 8)
    shadow = rays[:, 7] > 0.5
    hits = {}

    def ray_batch(r):
        return mi.Ray3f(mi.Point3f(*[mi.Float(np.ascontiguousarray(r[:, k])) for k in range(3)]),
                        mi.Vector3f(*[mi.Float(np.ascontiguousarray(r[:, k])) for k in range(3, 6)]),
                        mi.Float(np.ascontiguousarray(np.minimum(r[:, 6], 3.0e38))), mi.Float(0.0), [])

    closest, occl = ray_batch(rays[~shadow]), ray_batch(rays[shadow])

    def trace():
        pi = scene.ray_intersect_preliminary(closest)
        blocked = scene.ray_test(occl)
        hits["closest"], hits["blocked"] = dr.count(pi.is_valid()), dr.count(blocked)
        dr.eval(hits["closest"], hits["blocked"])

    render_s, trace_s = best(render), best(trace)
    print(json.dumps({"render_seconds": render_s, "trace_only_seconds": trace_s, "efficiency": trace_s / render_s,
                      "closest_rays": int((~shadow).sum()), "shadow_rays": int(shadow.sum()),
                      "closest_hit_fraction": int(hits["closest"][0]) / max(1, int((~shadow).sum())),
                      "shadow_blocked_fraction": int(hits["blocked"][0]) / max(1, int(shadow.sum())),
                      "spp": a.spp, "depth": a.depth}))


def cmd_initscene(a):
    gt = json.load(open(a.gt))
    os.makedirs(a.out, exist_ok=True)
    write_exr(os.path.join(a.out, "albedo.exr"), np.full((a.res, a.res, 3), 0.5, np.float32))
    objs = []
    for o in gt["objects"]:
        e = [1.0, 1.0, 1.0] if max(o.get("emission", [0, 0, 0])) > 0 else [0.0, 0.0, 0.0]
        objs.append({"id": o["id"], "name": o["name"], "roughness": 0.5, "specular": 0.5, "emission": e})
    scene = {"mesh": os.path.abspath(os.path.join(a.work, "atlas_mesh.ply")), "model": gt.get("model", "principled-v1"),
             "albedo_texture": "albedo.exr", "objects": objs}
    json.dump(scene, open(os.path.join(a.out, "scene.json"), "w"), indent=1)


def cmd_fit(a):
    mi = mitsuba()
    import drjit as dr
    scene = mi.load_file(a.scene_xml)
    base = os.path.dirname(os.path.abspath(a.transforms))
    sensors, refs = [], []
    for fr, get in frames(a.transforms):
        sensors.append(mi.load_dict(sensor_dict(mi, fr, get, 1)))
        refs.append(mi.TensorXf(np.array(mi.Bitmap(os.path.join(base, fr["file_path"])), dtype=np.float32)[:, :, :3]))
    integrator = prb(mi, a.depth)
    params = mi.traverse(scene)
    ka, ke = opt_keys(mi, params)
    params.keep([ka] + ke)
    opt = mi.ad.Adam(lr=a.lr, mask_updates=True)
    opt[ka] = params[ka]
    for k in ke:
        opt[k] = params[k]
        opt.set_learning_rate({k: a.lr_emission})
    params.update(opt)
    init_scene = json.load(open(a.init_scene))
    snapshots = sorted(float(s) for s in a.snapshots.split(","))
    rng = np.random.default_rng(a.seed)
    elapsed, it, losses, next_snap, iter_s = 0.0, 0, [], 0, []
    os.makedirs(a.out, exist_ok=True)
    while next_snap < len(snapshots):
        t0 = time.perf_counter()
        i = int(rng.integers(len(sensors)))
        img = mi.render(scene, params, sensor=sensors[i], integrator=integrator, spp=1, seed=it)
        loss = dr.mean(dr.square(img - refs[i]), axis=None)
        dr.backward(loss)
        opt.step()
        opt[ka] = dr.clip(opt[ka], 0.0, 1.0)
        for k in ke:
            opt[k] = dr.maximum(opt[k], 0.0)
        params.update(opt)
        dr.eval(params[ka])
        dr.sync_thread()
        dt = time.perf_counter() - t0
        elapsed += dt
        iter_s.append(dt)
        losses.append(float(loss.array[0]) if hasattr(loss, "array") else float(loss[0]))
        it += 1
        # Stop at a snapshot when the next iteration would overshoot it by more than half an iteration.
        while next_snap < len(snapshots) and elapsed + 0.5 * dt >= snapshots[next_snap]:
            d = os.path.join(a.out, "t%d" % next_snap)
            os.makedirs(d, exist_ok=True)
            alb = np.array(params[ka], dtype=np.float32)
            write_exr(os.path.join(d, "albedo.exr"), np.clip(alb, 0, 1))
            sc = json.loads(json.dumps(init_scene))
            for o in sc["objects"]:
                for k in ke:
                    if k.split(".emitter")[0] == o["name"]:
                        o["emission"] = [float(max(x, 0.0)) for x in np.array(params[k]).reshape(-1)[:3]]
            json.dump(sc, open(os.path.join(d, "scene.json"), "w"), indent=1)
            json.dump({"budget_s": snapshots[next_snap], "elapsed_s": elapsed, "iterations": it,
                       "median_iteration_s": statistics.median(iter_s), "last_loss": losses[-1],
                       "emission": {k: np.array(params[k]).reshape(-1).tolist() for k in ke}},
                      open(os.path.join(d, "mitsuba_fit.json"), "w"), indent=1)
            print("mitsuba fit: snapshot %d at %.1f s, %d iterations (%.2f s each), loss %.4g"
                  % (next_snap, elapsed, it, statistics.median(iter_s), losses[-1]), flush=True)
            next_snap += 1


# ---------------------------------------------------------------------------------------------
# table


def med(xs):
    return statistics.median(xs) if xs else float("nan")


def parse_relume_profile(path):
    txt = open(path).read()
    f = lambda pat: float(re.search(pat, txt).group(1))
    return {"primal": f(r"primal\s+([\d.]+) s"), "loss": f(r"loss\s+([\d.]+) s"),
            "direct": f(r"adjoint \(direct\)\s+([\d.]+) s"), "full": f(r"adjoint \(full\)\s+([\d.]+) s"),
            "rss": f(r"peak RSS ([\d.]+) MiB"), "floor": f(r"Embree alone\s+([\d.]+) s")}


def read_or(path, default):
    return open(path).read().strip() if os.path.exists(path) else default


def cmd_table(a):
    out = a.out
    lines = []
    P = lines.append
    meta = json.load(open(os.path.join(out, "meta.json")))
    P("# relume vs Mitsuba %s (prb, %s) on the room" % (meta["mitsuba"], meta["variant"]))
    P("")
    P("Machine: %s; %s. Load (uptime) at the start: %s; at the end: %s."
      % (meta["cpu"], meta["cores"], meta["uptime_start"], read_or(os.path.join(out, "uptime_end.txt"), "?")))
    P("")
    # (a)
    P("## (a) One gradient iteration")
    P("")
    P("relume: `relume profile --what adjoint --rays N --max-depth D --repeats 1`: primal + loss + adjoint pass "
      "(N random pixels of 8 room views, 1 sample each; gradients of every parameter group: albedo texture 1024^2, "
      "per-object roughness, specular, emission), 'full' = every vertex differentiated like prb, 'direct' = first vertex "
      "(what `fit` uses). Mitsuba: `peer_bench.py iter`: prb (max_depth D+1, no RR), mi.render of one held-out view "
      "at sqrt(N)^2 pixels and 1 spp + L2 loss against relume's 4-spp render + dr.backward over the albedo texture "
      "(1024^2) and both emitters' radiance, gradients evaluated; one timed iteration after a warm-up one (JIT). "
      "Each cell: median over %d interleaved rounds (relume, Mitsuba, relume, ...). Peak RSS = whole process "
      "(relume: its own report; Mitsuba: VmHWM, in brackets VmRSS after loading, before the first iteration). "
      "Embree floor: relume's primal and adjoint-pass rays of that iteration replayed through Embree alone "
      "(`rtcIntersect1` / `rtcOccluded1`), the iteration's cost if all else were free; Mitsuba traces with Embree "
      "too, so Mitsuba / floor bounds how much faster than Mitsuba any relume built on this traversal can be."
      % meta["rounds"])
    P("")
    P("| rays | depth | relume full (s) | relume direct (s) | Mitsuba prb (s) | Mitsuba / relume full | relume Embree floor (s) | Mitsuba / floor | relume peak RSS (MiB) | Mitsuba peak RSS (MiB) [loaded] |")
    P("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    ratios = []
    rows = {}
    for s in meta["settings"]:
        n, d = s
        rel = [parse_relume_profile(p) for p in sorted(glob.glob(os.path.join(out, "iter", "relume_%d_%d_r*.txt" % (n, d))))]
        mts = [json.loads(open(p).read().strip().splitlines()[-1]) for p in
               sorted(glob.glob(os.path.join(out, "iter", "mitsuba_%d_%d_r*.json" % (n, d))))]
        if not rel or not mts:
            continue
        rf = med([r["primal"] + r["loss"] + r["full"] for r in rel])
        rd = med([r["primal"] + r["loss"] + r["direct"] for r in rel])
        mt = med([min(m["seconds"]) for m in mts])
        # ratio: median of per-round ratios (paired, same load)
        per = [min(m["seconds"]) / (r["primal"] + r["loss"] + r["full"]) for r, m in zip(rel, mts)]
        ratios.append(med(per))
        rows[(n, d)] = (rf, mt, med([r["rss"] for r in rel]), med([m["peak_rss_mib"] for m in mts]))
        floor = [min(m["seconds"]) / r["floor"] for r, m in zip(rel, mts)]
        P("| %d | %d | %.3f | %.3f | %.3f | %.2fx (rounds: %s) | %.3f | %.2fx | %.0f | %.0f [%.0f] |" % (
            mts[0]["rays"], d, rf, rd, mt, med(per), ", ".join("%.2f" % x for x in per), med([r["floor"] for r in rel]),
            med(floor), med([r["rss"] for r in rel]),
            med([m["peak_rss_mib"] for m in mts]), med([m["rss_loaded_mib"] for m in mts])))
    P("")
    depth_rows = sorted(k for k in rows if k[0] == meta["depth_rays"])
    if len(depth_rows) >= 2:
        lo, hi = depth_rows[0], depth_rows[-1]
        P("Growth with depth (%d rays, depth %d -> %d): time relume x%.2f, Mitsuba x%.2f; peak RSS relume %+.0f MiB, Mitsuba %+.0f MiB."
          % (lo[0], lo[1], hi[1], rows[hi][0] / rows[lo][0], rows[hi][1] / rows[lo][1], rows[hi][2] - rows[lo][2],
             rows[hi][3] - rows[lo][3]))
    batch_rows = sorted(k for k in rows if k[1] == meta["batch_depth"])
    if len(batch_rows) >= 2:
        lo, hi = batch_rows[0], batch_rows[-1]
        P("Growth with batch (depth %d, %d -> %d rays): time relume x%.2f, Mitsuba x%.2f; peak RSS relume %+.0f MiB, Mitsuba %+.0f MiB."
          % (lo[1], lo[0], hi[0], rows[hi][0] / rows[lo][0], rows[hi][1] / rows[lo][1], rows[hi][2] - rows[lo][2],
             rows[hi][3] - rows[lo][3]))
    P("")
    # (e)
    eff_rel = sorted(glob.glob(os.path.join(out, "eff", "relume_r*.txt")))
    eff_mts = sorted(glob.glob(os.path.join(out, "eff", "mitsuba_r*.json")))
    if eff_rel and eff_mts:
        P("## (e) Renderer efficiency: each tracer's render against its own Embree traversal alone on the same rays")
        P("")
        P("One held-out view, 256^2 pixels, 4 spp, depth 8 (no AD, no Russian roulette). relume: `relume profile --what "
          "render --scene --cameras --spp 4 --max-depth 8 --rays-out` (render best of 5; its rays replayed with "
          "`rtcIntersect1` / `rtcOccluded1`, best of 5). Mitsuba: `peer_bench.py efficiency`: `path` integrator "
          "(max_depth 9) render of the same camera, then the same rays (relume's, read from the file) through "
          "`ray_intersect_preliminary` / `ray_test`, best of 3 after a warm-up (JIT). Rounds interleaved.")
        P("")
        P("| round | relume render (s) | relume Embree alone (s) | relume efficiency | Mitsuba render (s) | Mitsuba Embree alone (s) | Mitsuba efficiency | relume / Mitsuba render |")
        P("| --- | --- | --- | --- | --- | --- | --- | --- |")
        rr, mm = [], []
        for k, (rp, mp) in enumerate(zip(eff_rel, eff_mts)):
            txt = open(rp).read()
            f = lambda pat: float(re.search(pat, txt).group(1))
            r = {"render": f(r"render\s+([\d.]+) s"), "trace": f(r"trace only\s+([\d.]+) s")}
            m = json.loads(open(mp).read().strip().splitlines()[-1])
            rr.append(r)
            mm.append(m)
            P("| %d | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.2fx |" % (
                k + 1, r["render"], r["trace"], r["trace"] / r["render"], m["render_seconds"], m["trace_only_seconds"],
                m["efficiency"], r["render"] / m["render_seconds"]))
        P("| median | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %.2fx |" % (
            med([r["render"] for r in rr]), med([r["trace"] for r in rr]), med([r["trace"] / r["render"] for r in rr]),
            med([m["render_seconds"] for m in mm]), med([m["trace_only_seconds"] for m in mm]),
            med([m["efficiency"] for m in mm]), med([r["render"] / m["render_seconds"] for r, m in zip(rr, mm)])))
        P("")
        P("Rays: %d closest hits (%.4f%% hit in Mitsuba's copy of the scene), %d shadow rays." % (
            mm[-1]["closest_rays"], 100 * mm[-1]["closest_hit_fraction"], mm[-1]["shadow_rays"]))
        P("")
    # (b)
    P("## (b) Forward agreement (scripts/mitsuba_compare.sh, Mitsuba scalar_rgb on the exported ground truth)")
    P("")
    fwd = read_or(os.path.join(out, "forward.txt"), "(not run)").splitlines()
    P("```")
    for l in fwd:
        P(l)
    P("```")
    P("")
    # (c)
    P("## (c) Time to accuracy: albedo texture + emission, equal wall clock")
    P("")
    P("relume: `relume prepare --res %d` once, then `relume fit --config C --time-budget B --no-report` with C = `%s` "
      "and B the budget less prepare's time; "
      "time = wall clock of the prepare process + the fit process (loading, all stages, writing the result). "
      "Mitsuba: `peer_bench.py fit` (prb depth 9+1, Adam(mask_updates=True), lr 0.05 albedo / 0.5 emission, one random "
      "training frame per iteration at 256x192, 1 spp; from albedo 0.5, emission (1,1,1) on the two true emitters), "
      "its clock started after loading the scene and frames, snapshots at the budgets. "
      "Both scored by `relume eval --truth cap/gt/scene.json --coverage work/coverage.exr` (albedo MAE over the "
      "texels observed >= 5 times, in relume's atlas at %d^2; emission error over the true emitters)."
      % (meta["res"], json.dumps(meta["fit_config"]), meta["res"]))
    P("")
    P("| budget | wall clock (s) | relume iterations | relume albedo MAE | Mitsuba iterations | Mitsuba albedo MAE | relume emission error | Mitsuba emission error | load (1 min) relume / Mitsuba |")
    P("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    runs_path = os.path.join(out, "fit", "relume_runs.json")
    fit = json.load(open(runs_path)) if os.path.exists(runs_path) else []
    for k, r in enumerate(fit):
        ev_r = json.load(open(os.path.join(out, "fit", "relume_%d" % k, "eval", "eval.json")))
        mdir = os.path.join(out, "fit", "mitsuba", "t%d" % k)
        if not os.path.exists(os.path.join(mdir, "eval", "eval.json")):
            continue
        ev_m = json.load(open(os.path.join(mdir, "eval", "eval.json")))
        mf = json.load(open(os.path.join(mdir, "mitsuba_fit.json")))
        tr, tm = ev_r["truth"], ev_m["truth"]
        P("| %d s | %.0f (relume) / %.0f (Mitsuba) | %d | %.4f | %d (%.2f s each) | %.4f | %.1f%% | %.1f%% | %s / %s |" % (
            r["budget"], r["seconds"], mf["elapsed_s"], r["iterations"], tr["albedo_mae"], mf["iterations"],
            mf["median_iteration_s"], tm["albedo_mae"], 100 * tr["emission_rel_error"], 100 * tm["emission_rel_error"],
            r["load"], open(os.path.join(out, "fit", "mitsuba_load.txt")).read().strip()))
    P("")
    P("Ratios across the whole of (a): Mitsuba / relume(full) per iteration, median %.2fx (range %.2f-%.2f)."
      % (med(ratios), min(ratios), max(ratios)) if ratios else "")
    text = "\n".join(lines) + "\n"
    open(os.path.join(out, "peer.md"), "w").write(text)
    sys.stdout.write(text)


def cmd_relumefits(a):
    """relume fit at each budget, as a user runs it: `relume fit WORK --time-budget T --no-report`, T
    the budget less prepare's wall clock. The time is prepare's wall clock plus the fit process's
    (start to exit: loading, every stage, the result)."""
    import shutil, subprocess
    budgets = [float(b) for b in a.budgets.split(",")]
    cfgp = os.path.join(a.out, "fit_config.json")
    json.dump(json.loads(a.config), open(cfgp, "w"))
    runs = []
    for k, T in enumerate(budgets):
        work = a.work
        for f in ("checkpoint.bin", "metrics.jsonl"):
            if os.path.exists(os.path.join(work, f)):
                os.remove(os.path.join(work, f))
        load = open("/proc/loadavg").read().split()[0]
        t0 = time.perf_counter()
        proc = subprocess.run([a.relume, "--log", "info", "fit", work, "--config", cfgp, "--no-report",
                               "--time-budget", "%.1f" % (T - a.prepare_seconds)],
                              stderr=subprocess.STDOUT, stdout=subprocess.PIPE, text=True, errors="replace")
        t_fit = time.perf_counter() - t0
        log = [part.rstrip() for line in proc.stdout.splitlines() for part in line.split("\r") if "info" in part]
        m = re.search(r"fit: (\d+) iterations in", proc.stdout)
        if proc.returncode != 0 or not m:
            sys.exit("peer_bench.py: relume fit failed:\n" + "\n".join(log[-20:]))
        dst = os.path.join(a.out, "relume_%d" % k)
        if os.path.exists(dst):
            shutil.rmtree(dst)
        os.rename(os.path.join(work, "result"), dst)
        open(os.path.join(a.out, "relume_%d.log" % k), "w").write("\n".join(log) + "\n")
        r = {"budget": T, "seconds": t_fit + a.prepare_seconds, "fit_seconds": t_fit, "iterations": int(m.group(1)),
             "load": load}
        print("relume fit: budget %.0f s: %.1f s (prepare %.1f + fit %.1f), %d iterations, load %s"
              % (T, r["seconds"], a.prepare_seconds, t_fit, r["iterations"], load), flush=True)
        runs.append(r)
    json.dump(runs, open(os.path.join(a.out, "relume_runs.json"), "w"), indent=1)


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else ""
    ap = argparse.ArgumentParser(prog="peer_bench.py " + mode)
    if mode == "camera":
        ap.add_argument("transforms"); ap.add_argument("out"); ap.add_argument("--rays", type=int, required=True)
        cmd_camera(ap.parse_args(sys.argv[2:]))
    elif mode == "iter":
        for k in ("scene_xml", "transforms", "ref"):
            ap.add_argument(k)
        ap.add_argument("--depth", type=int, required=True)
        ap.add_argument("--repeats", type=int, default=2)
        ap.add_argument("--seed", type=int, default=1)
        cmd_iter(ap.parse_args(sys.argv[2:]))
    elif mode == "efficiency":
        for k in ("scene_xml", "transforms", "rays"):
            ap.add_argument(k)
        ap.add_argument("--spp", type=int, default=4)
        ap.add_argument("--depth", type=int, required=True)
        ap.add_argument("--repeats", type=int, default=3)
        cmd_efficiency(ap.parse_args(sys.argv[2:]))
    elif mode == "initscene":
        ap.add_argument("gt"); ap.add_argument("work"); ap.add_argument("out"); ap.add_argument("--res", type=int, default=512)
        cmd_initscene(ap.parse_args(sys.argv[2:]))
    elif mode == "fit":
        for k in ("scene_xml", "transforms", "init_scene", "out"):
            ap.add_argument(k)
        ap.add_argument("--snapshots", required=True)
        ap.add_argument("--depth", type=int, default=9)
        ap.add_argument("--lr", type=float, default=0.05)
        ap.add_argument("--lr-emission", type=float, default=0.5)
        ap.add_argument("--seed", type=int, default=1)
        cmd_fit(ap.parse_args(sys.argv[2:]))
    elif mode == "relumefits":
        for k in ("relume", "work", "out"):
            ap.add_argument(k)
        ap.add_argument("--budgets", required=True)
        ap.add_argument("--config", required=True)
        ap.add_argument("--prepare-seconds", type=float, required=True)
        cmd_relumefits(ap.parse_args(sys.argv[2:]))
    elif mode == "table":
        ap.add_argument("out")
        cmd_table(ap.parse_args(sys.argv[2:]))
    else:
        sys.exit("peer_bench.py: mode must be camera, iter, initscene, fit or table, not '%s'" % mode)


main()
