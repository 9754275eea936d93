"""Blender/Cycles side of scripts/bench/bench_cycles.sh: builds the benchmark scene from scratch and renders it.

Run inside Blender (never imported by the system Python):
    blender -b --factory-startup --python scripts/bench/cycles_scene.py -- JOB.json

JOB.json (written by scripts/bench/bench_cycles.py):
    {"scene": {...envkit-frame geometry, see bench_cycles.py...}, "hdri": "/path/x.exr", "threads": 2,
     "renders": [{"spp": 16, "seed": 1, "output": "/path/out.exr"}, ...], "timings": "/path/timings.json",
     "cycles_settings": {"max_bounces": 2, "blur_glossy": 1.0, ...}}   (optional: scene.cycles attributes that
     replace the settings below; bench_indirect.py)

Geometry is given in envkit's world frame (+Y up) and moved to Blender's with Blender (x, y, z) = envkit
(x, -z, y), the axis change of envkit's `blender` convention (libenv/maps/include/envkit/maps/convention.h), so that the
HDRI loaded with Blender's default world mapping and the same file read by envrender with "convention":
"blender" show the same sky in the same directions.

Cycles settings: CPU, fixed thread count, direct light only (max_bounces 0: the BSDF-sampled ray is still traced
to the world for MIS, the next surface is not shaded), no clamping, no glossy filter, no denoising, no adaptive
sampling, box pixel filter 1 px wide, world importance map 1024, environment texture looked up with Closest
(envrender looks the map up at the nearest texel). Meshes are read from the job's OBJ files (flat-shaded
triangles). Spheres are point-cloud points (Cycles renders them as exact
spheres) made by a geometry-nodes Points node. Glossy spheres: Glossy BSDF, GGX, roughness = sqrt(alpha) (Cycles
squares it), white: a Fresnel-less GGX reflector.

Timing: persistent data on, one 1-spp warm-up render first (scene sync, BVH, world importance map, image
load); each listed render is then timed as the wall time of bpy.ops.render.render() (path tracing plus Cycles'
per-render fixed cost: film allocation, session start), excluding Blender start-up and the EXR write.
"""
import json
import math
import sys
import time

import bpy


def to_blender(v):
    x, y, z = v
    return (x, -z, y)


def build(scene_spec, hdri, threads):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = 1
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.use_preview_denoising = False
    c.max_bounces = 0
    c.diffuse_bounces = 0
    c.glossy_bounces = 0
    c.transmission_bounces = 0
    c.volume_bounces = 0
    c.transparent_max_bounces = 0
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.light_sampling_threshold = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.use_animated_seed = False
    c.seed = 0
    if hasattr(c, "use_auto_tile"):
        c.use_auto_tile = False
    scene.render.film_transparent = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads
    scene.render.use_persistent_data = True
    scene.render.use_compositing = False
    scene.render.use_sequencer = False
    scene.render.dither_intensity = 0.0
    cam_spec = scene_spec["camera"]
    w, h = cam_spec["resolution"]
    scene.render.resolution_x = w
    scene.render.resolution_y = h
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = 1.0
    scene.render.pixel_aspect_y = 1.0
    crop = scene_spec.get("crop")  # x0, y0, x1, y1 in pixels, row 0 on top, x1 / y1 exclusive
    if crop:
        # Blender's border is a fraction of the frame from the bottom left, turned into pixels by truncation: a
        # quarter pixel past each edge lands on it whatever the float rounding.
        x0, y0, x1, y1 = crop
        scene.render.use_border = True
        scene.render.use_crop_to_border = True
        scene.render.border_min_x, scene.render.border_max_x = (x0 + 0.25) / w, (x1 + 0.25) / w
        scene.render.border_min_y, scene.render.border_max_y = (h - y1 + 0.25) / h, (h - y0 + 0.25) / h
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"

    # World: the HDRI, Blender's default equirectangular mapping.
    world = bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    nt = world.node_tree
    nt.nodes.clear()
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(hdri)
    tex.image.colorspace_settings.name = "Linear"
    tex.interpolation = "Closest"
    tex.projection = "EQUIRECTANGULAR"
    bg = nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = float(scene_spec.get("intensity", 1.0))
    out = nt.nodes.new("ShaderNodeOutputWorld")
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    nt.links.new(bg.outputs["Background"], out.inputs["Surface"])
    world.cycles.sampling_method = "MANUAL"
    world.cycles.sample_map_resolution = 1024

    # Camera: pinhole, vertical field of view (envrender's fov is vertical).
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "VERTICAL"
    cam_data.angle_y = math.radians(cam_spec["fov"])
    cam_data.clip_start = 1e-3
    cam_data.clip_end = 1e5
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    from mathutils import Matrix, Vector
    pos = Vector(to_blender(cam_spec["position"]))
    target = Vector(to_blender(cam_spec["look_at"]))
    up = Vector(to_blender(cam_spec.get("up", [0, 1, 0])))
    f = (target - pos).normalized()
    r = f.cross(up).normalized()
    u = r.cross(f).normalized()
    rot = Matrix(((r.x, u.x, -f.x), (r.y, u.y, -f.y), (r.z, u.z, -f.z)))
    cam.matrix_world = Matrix.Translation(pos) @ rot.to_4x4()
    scene.camera = cam

    def material(name, spec):
        m = bpy.data.materials.new(name)
        m.use_nodes = True
        mt = m.node_tree
        mt.nodes.clear()
        o = mt.nodes.new("ShaderNodeOutputMaterial")
        if spec["type"] == "diffuse":
            b = mt.nodes.new("ShaderNodeBsdfDiffuse")
            a = spec["albedo"]
            a = a if isinstance(a, list) else [a, a, a]
            b.inputs["Color"].default_value = (a[0], a[1], a[2], 1.0)
            b.inputs["Roughness"].default_value = 0.0
        else:  # Fresnel-less GGX: envrender conductor eta 0, k > 0
            b = mt.nodes.new("ShaderNodeBsdfGlossy")
            b.distribution = "GGX"
            b.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
            b.inputs["Roughness"].default_value = math.sqrt(spec["roughness"])
        mt.links.new(b.outputs["BSDF"], o.inputs["Surface"])
        return m

    mats = {name: material(name, spec) for name, spec in scene_spec["materials"].items()}

    g = scene_spec["ground"]
    s = g["half_size"]
    mesh = bpy.data.meshes.new("ground")
    mesh.from_pydata([to_blender(p) for p in ([-s, 0, -s], [s, 0, -s], [s, 0, s], [-s, 0, s])], [],
                     [(0, 1, 2, 3)])
    mesh.materials.append(mats[g["material"]])
    ground = bpy.data.objects.new("ground", mesh)
    scene.collection.objects.link(ground)

    for i, sph in enumerate(scene_spec["spheres"]):
        ng = bpy.data.node_groups.new(f"sphere{i}", "GeometryNodeTree")
        ng.outputs.new("NodeSocketGeometry", "Geometry")
        pts = ng.nodes.new("GeometryNodePoints")
        pts.inputs["Count"].default_value = 1
        pts.inputs["Position"].default_value = to_blender(sph["center"])
        pts.inputs["Radius"].default_value = sph["radius"]
        setm = ng.nodes.new("GeometryNodeSetMaterial")
        setm.inputs["Material"].default_value = mats[sph["material"]]
        gout = ng.nodes.new("NodeGroupOutput")
        ng.links.new(pts.outputs["Geometry"], setm.inputs["Geometry"])
        ng.links.new(setm.outputs["Geometry"], gout.inputs["Geometry"])
        obj = bpy.data.objects.new(f"sphere{i}", bpy.data.meshes.new(f"sphere{i}_base"))
        scene.collection.objects.link(obj)
        mod = obj.modifiers.new("points", "NODES")
        mod.node_group = ng

    # OBJ meshes (written by bench_cycles.py: "v x y z" and "f a b c" lines, envkit frame), flat-shaded as
    # envrender shades a mesh without vertex normals.
    for m in scene_spec.get("meshes", []):
        verts, faces = [], []
        with open(m["file"]) as fh:
            for line in fh:
                parts = line.split()
                if parts and parts[0] == "v":
                    verts.append(to_blender([float(v) for v in parts[1:4]]))
                elif parts and parts[0] == "f":
                    faces.append([int(v.split("/")[0]) - 1 for v in parts[1:]])
        mesh = bpy.data.meshes.new(m["name"])
        mesh.from_pydata(verts, [], faces)
        mesh.materials.append(mats[m["material"]])
        obj = bpy.data.objects.new(m["name"], mesh)
        scene.collection.objects.link(obj)
    return scene


def render(scene, spp, seed):
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    scene.update_tag()
    bpy.context.view_layer.update()
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=False)
    return time.perf_counter() - t0


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    with open(argv[0]) as fh:
        job = json.load(fh)
    scene = build(job["scene"], job["hdri"], int(job.get("threads", 2)))
    # Settings that replace build()'s, e.g. bounces and Filter Glossy (bench_indirect.py).
    for key, value in job.get("cycles_settings", {}).items():
        setattr(scene.cycles, key, value)
    warm = render(scene, 1, 12345)
    timings = {"warmup_seconds": warm, "renders": [], "blender": bpy.app.version_string,
               "sampling_pattern": scene.cycles.sampling_pattern}
    for r in job["renders"]:
        sec = render(scene, int(r["spp"]), int(r["seed"]))
        bpy.data.images["Render Result"].save_render(r["output"], scene=scene)
        timings["renders"].append({"spp": r["spp"], "seed": r["seed"], "output": r["output"], "seconds": sec})
        print(f"cycles_scene: {r['output']} {r['spp']} spp {sec:.3f} s", flush=True)
    with open(job["timings"], "w") as fh:
        json.dump(timings, fh, indent=1)


main()
