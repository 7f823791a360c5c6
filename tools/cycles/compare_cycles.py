"""Lightloom against Blender Cycles on the sharp-sun scene (tests/projects/sharp_sun.ron), after
each kind of edit an artist makes.

Run inside Blender (Debian `blender`, 3.4):

    blender -b --factory-startup -P tools/cycles/compare_cycles.py -- [--width 320 --height 180]
        [--spp 1,2,4,8,16,32,64] [--reference-spp 1024] [--threads 2] [--lightloom target/release/lightloom]
        [--edits rotation,brdf,sun]

The edits: an environment rotation (yaw 40 degrees), a BRDF edit (Lambert to GGX, roughness 0.5,
F0 1 so that Fresnel is 1 in both renderers, specular colour 0.3; Cycles adds a GGX Glossy BSDF
to the Diffuse one) and a light move (the sun from 40 to 25 degrees of elevation). For each, Cycles
renders the edited scene from scratch at each sample count, and Lightloom's time is
`lightloom accuracy --edit`'s: from the edit to its frame drawn (the stages the edit changed, the
relight, the draw), with the project drawn before it.

It builds the same scene in Cycles: the floor and the sphere with their Lambert albedos (the
BRDF editor's 0.8 times each object's colour), the procedural sky of nodes/src/sky.rs sampled
into a 2048x1024 equirect (Blender is Z up; Lightloom's (x, y, z) is Blender's (x, -z, y)), the
same pinhole camera, direct light only (no bounces), a box pixel filter, 2 threads. It renders
a converged Cycles reference, then Cycles at each sample count (timed: scene sync, BVH and
render, what an artist waits for after an edit), and Lightloom's modes through `lightloom
render` (EXR, linear). Every image's error is the relative RMSE against the Cycles reference
over pixels the geometry covers: sqrt(mean over pixels and channels of the squared
difference) / mean reference radiance. Lightloom's times are `lightloom accuracy --edit`'s
(the edit's own stages in a fresh engine, the relight, the draw) and a steady frame.

Cycles 3.4's GGX masking is separable, G1(i) G1(o); Lightloom's is height-correlated,
1 / (1 + Lambda_i + Lambda_o). At roughness 0.5 they differ by well under 1% except at grazing
angles.

For each edit it prints Cycles' time at Lightloom's error (log-log interpolation between its
sample counts) over Lightloom's edit-to-frame time: how many times sooner the edit reaches the
screen at equal error.
"""

import json
import math
import os
import subprocess
import sys
import tempfile
import time

import bpy
import numpy as np

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []


def option(name, default):
    if name in argv:
        return argv[argv.index(name) + 1]
    return default


ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
WIDTH = int(option("--width", "320"))
HEIGHT = int(option("--height", "180"))
SPP = [int(s) for s in option("--spp", "1,2,4,8,16,32,64").split(",")]
REFERENCE_SPP = int(option("--reference-spp", "1024"))
THREADS = int(option("--threads", "2"))
LIGHTLOOM = option("--lightloom", os.path.join(ROOT, "target", "release", "lightloom"))
PROJECT = os.path.join(ROOT, "tests", "projects", "sharp_sun.ron")
EDIT_NAMES = option("--edits", "rotation,brdf,sun").split(",")

# tests/projects/sharp_sun.ron, spelled out (the project is the source of truth; keep in step).
SUN_ELEVATION, SUN_AZIMUTH, SUN_INTENSITY, SUN_RADIUS_DEG = 40.0, 30.0, 2500.0, 0.8
ZENITH, HORIZON, GROUND = np.array([0.25, 0.45, 0.9]), np.array([0.9, 0.95, 1.0]), np.array([0.25, 0.22, 0.2])
FLOOR_SIZE, FLOOR_ALBEDO = 8.0, 0.8 * 0.8
SPHERE_RADIUS, SPHERE_CENTRE, SPHERE_ALBEDO = 0.75, (0.0, 0.75, 0.0), 0.8 * 0.8
CAMERA_POSITION, CAMERA_TARGET, FOV_Y_DEG = (0.0, 2.0, 5.0), (0.0, 0.5, 0.0), 40.0


def to_blender(v):
    x, y, z = v
    return (x, -z, y)


def smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


# Each edit: Lightloom's assignments and the same change to the Cycles scene.
EDITS = {
    "rotation": ("environment rotation, yaw 40 deg", ["sky.rotation=40,0,0"], {"yaw": 40.0}),
    "brdf": ("BRDF edit, Lambert to GGX 0.5", ["material.model=ggx", "material.roughness=0.5", "material.f0=1",
                                               "material.specular=0.3,0.3,0.3"], {"glossy": (0.5, 0.3)}),
    "sun": ("light move, sun elevation 40 to 25 deg", ["sky.sun_elevation=25"], {"sun_elevation": 25.0}),
}


def rotate_yaw(d, yaw_deg):
    """R^-1 d for the Environment's R = Ry(yaw) (nodes/src/kinds/environment.rs rotation_matrix):
    the turned sky's radiance toward d is the unturned sky's toward R^-1 d."""
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    return np.stack([c * x - s * z, y, s * x + c * z], axis=-1)


def sky_radiance(d, sun_elevation=SUN_ELEVATION, yaw=0.0):
    """nodes/src/sky.rs ProceduralSky::radiance for Lightloom directions d (N x 3, unit), turned
    by the Environment's yaw."""
    d = rotate_yaw(d, yaw)
    e, a = math.radians(sun_elevation), math.radians(SUN_AZIMUTH)
    sun = np.array([math.cos(e) * math.sin(a), math.sin(e), -math.cos(e) * math.cos(a)])
    y = d[:, 1:2]
    t_up = np.sqrt(np.clip(y, 0.0, None))
    up = HORIZON * (1.0 - t_up) + ZENITH * t_up
    t_down = np.clip(-y * 8.0, None, 1.0)
    down = HORIZON * 0.5 * (1.0 - t_down) + GROUND * t_down
    out = np.where(y >= 0.0, up, down)
    angle = np.arccos(np.clip(d @ sun, -1.0, 1.0))[:, None]
    radius = math.radians(SUN_RADIUS_DEG)
    disk = 1.0 - smoothstep(radius * 0.8, radius * 1.2, angle)
    aureole = 0.02 * np.exp(-((angle / (6.0 * radius)) ** 2))
    return out + np.array([1.0, 0.925, 0.8]) * SUN_INTENSITY * (disk + aureole)


def environment_image(width=2048, height=1024, supersample=3, **sky):
    acc = np.zeros((height, width, 3))
    for sy in range(supersample):
        for sx in range(supersample):
            u = (np.arange(width) + (sx + 0.5) / supersample) / width
            v = (np.arange(height) + (sy + 0.5) / supersample) / height
            uu, vv = np.meshgrid(u, v)
            # Blender's equirect (direction_to_equirectangular): u = 1/2 - atan2(y, x) / 2pi,
            # v = 1/2 + atan2(z, hypot(x, y)) / pi.
            phi, el = (0.5 - uu) * 2.0 * math.pi, (vv - 0.5) * math.pi
            bx, by, bz = np.cos(phi) * np.cos(el), np.sin(phi) * np.cos(el), np.sin(el)
            d = np.stack([bx, bz, -by], axis=-1).reshape(-1, 3)
            acc += sky_radiance(d, **sky).reshape(height, width, 3)
    rgb = acc / supersample**2
    image = bpy.data.images.new("sky", width, height, float_buffer=True)
    rgba = np.concatenate([rgb, np.ones((height, width, 1))], axis=-1)
    image.pixels.foreach_set(rgba.astype(np.float32).ravel())
    return image


def material(name, albedo, glossy=None):
    """Lambert albedo, plus with glossy = (roughness, colour) a GGX lobe with Fresnel 1 (Lightloom's
    GGX at F0 = 1; both take alpha = roughness^2)."""
    material = bpy.data.materials.new(name)
    material.use_nodes = True
    nodes = material.node_tree.nodes
    links = material.node_tree.links
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (albedo, albedo, albedo, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    out = nodes.new("ShaderNodeOutputMaterial")
    if glossy is None:
        links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
        return material
    roughness, colour = glossy
    lobe = nodes.new("ShaderNodeBsdfGlossy")
    lobe.distribution = "GGX"
    lobe.inputs["Color"].default_value = (colour, colour, colour, 1.0)
    lobe.inputs["Roughness"].default_value = roughness
    add = nodes.new("ShaderNodeAddShader")
    links.new(bsdf.outputs["BSDF"], add.inputs[0])
    links.new(lobe.outputs["BSDF"], add.inputs[1])
    links.new(add.outputs["Shader"], out.inputs["Surface"])
    return material


def build_scene(yaw=0.0, sun_elevation=SUN_ELEVATION, glossy=None):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=FLOOR_SIZE, location=(0.0, 0.0, 0.0))
    bpy.context.object.data.materials.append(material("floor", FLOOR_ALBEDO, glossy))
    bpy.ops.mesh.primitive_uv_sphere_add(radius=SPHERE_RADIUS, location=to_blender(SPHERE_CENTRE), segments=128, ring_count=64)
    bpy.ops.object.shade_smooth()
    bpy.context.object.data.materials.append(material("sphere", SPHERE_ALBEDO, glossy))
    world = bpy.data.worlds.new("sky")
    world.use_nodes = True
    nodes = world.node_tree.nodes
    nodes.clear()
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = environment_image(yaw=yaw, sun_elevation=sun_elevation)
    texture.interpolation = "Linear"
    background = nodes.new("ShaderNodeBackground")
    out = nodes.new("ShaderNodeOutputWorld")
    world.node_tree.links.new(texture.outputs["Color"], background.inputs["Color"])
    world.node_tree.links.new(background.outputs["Background"], out.inputs["Surface"])
    scene.world = world
    camera_data = bpy.data.cameras.new("camera")
    camera_data.sensor_fit = "VERTICAL"
    camera_data.angle_y = math.radians(FOV_Y_DEG)
    camera = bpy.data.objects.new("camera", camera_data)
    scene.collection.objects.link(camera)
    import mathutils

    position, target = mathutils.Vector(to_blender(CAMERA_POSITION)), mathutils.Vector(to_blender(CAMERA_TARGET))
    camera.location = position
    camera.rotation_mode = "QUATERNION"
    camera.rotation_quaternion = (target - position).to_track_quat("-Z", "Y")
    scene.camera = camera
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.render.threads_mode = "FIXED"
    scene.render.threads = THREADS
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = 0
    scene.cycles.pixel_filter_type = "BOX"
    scene.cycles.filter_width = 1.0
    scene.render.film_transparent = True
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.color_mode = "RGBA"
    scene.view_settings.view_transform = "Standard"
    return scene


def read_exr(path):
    """An EXR's RGBA pixels (rows as Blender stores them, the same for both renderers)."""
    image = bpy.data.images.load(path, check_existing=False)
    w, h = image.size
    pixels = np.empty(w * h * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(h, w, 4)


def render(scene, spp, path, seed):
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    scene.render.filepath = path
    start = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.perf_counter() - start


def relative_rmse(image, reference, mask):
    diff = (image[..., :3] - reference[..., :3])[mask]
    return math.sqrt(float(np.mean(diff**2))) / float(np.mean(reference[..., :3][mask]))


def cycles_time_at(error, cycles):
    """Cycles' time to reach `error`, log-log interpolated between its (seconds, error) rows; None
    when no sample count reached it."""
    rows = sorted(cycles, key=lambda r: r[1], reverse=True)
    for (t0, e0), (t1, e1) in zip(rows, rows[1:]):
        if e1 <= error <= e0:
            if e0 == e1:
                return t0
            f = math.log(error / e0) / math.log(e1 / e0)
            return math.exp(math.log(t0) + f * (math.log(t1) - math.log(t0)))
    if rows and error >= rows[0][1]:
        return rows[0][0]
    return None


def compare(out, name):
    label, assignments, cycles_scene = EDITS[name]
    print(f"\n== {label} ({' '.join(assignments)}) ==")
    scene = build_scene(**cycles_scene)
    reference_path = os.path.join(out, f"{name}_reference.exr")
    reference_s = render(scene, REFERENCE_SPP, reference_path, 1)
    reference = read_exr(reference_path)
    mask = reference[..., 3] > 0.999
    print(f"converged reference: {REFERENCE_SPP} spp in {reference_s:.1f} s ({int(mask.sum())} covered pixels)")
    # The reference's own noise: a second one, differenced, over sqrt(2).
    second_path = os.path.join(out, f"{name}_reference2.exr")
    render(scene, REFERENCE_SPP, second_path, 2)
    noise = relative_rmse(read_exr(second_path), reference, mask) / math.sqrt(2.0)
    print(f"its own noise: {100 * noise:.2f}% relative RMSE")
    rows, cycles = [], []
    for spp in SPP:
        path = os.path.join(out, f"{name}_cycles_{spp}.exr")
        seconds = render(scene, spp, path, 100 + spp)
        error = relative_rmse(read_exr(path), reference, mask)
        cycles.append((seconds, error))
        rows.append(("Cycles", f"{spp} spp", seconds * 1e3, None, error, None))
    edits = [arg for a in assignments for arg in ("--edit", a)]
    report = subprocess.run(
        [LIGHTLOOM, "accuracy", PROJECT, "--json", "--samples", "16", "--width", str(WIDTH), "--height", str(HEIGHT),
         "--bands", "6", "--wavelets", "320", "--adaptive", "--square-lights", "--sun", "separate"] + edits,
        check=True, capture_output=True, text=True).stdout
    timings = {(r["mode"].split(" ")[0], r["coefficients"], r["sun"]): r for r in json.loads(report)["rows"]}
    for (mode, coefficients, sun), row in timings.items():
        if mode == "sh_irradiance":
            continue
        path = os.path.join(out, f"{name}_lightloom_{mode}_{coefficients}_{sun}.exr")
        overrides = ["--set", f"output.mode={mode}", "--set", f"output.sun={sun}", "--set", "output.background=false"]
        overrides += [arg for a in assignments for arg in ("--set", a)]
        if mode == "sh_prt":
            overrides += ["--set", f"scene.transport_bands={int(math.sqrt(coefficients))}",
                          "--set", f"sky.sh_bands={int(math.sqrt(coefficients))}"]
        if mode.startswith("wavelet"):
            overrides += ["--set", f"output.wavelet_terms={coefficients}"]
        subprocess.run([LIGHTLOOM, "render", PROJECT, "-o", path, "--width", str(WIDTH), "--height", str(HEIGHT), "-q"]
                       + overrides, check=True, capture_output=True)
        error = relative_rmse(read_exr(path), reference, mask)
        cycles_s = cycles_time_at(error, cycles)
        sooner = f"{cycles_s * 1e3 / row['edit_ms']:.1f}x" if cycles_s is not None else "Cycles never reached it"
        rows.append((f"Lightloom {mode} {coefficients}", "edit to frame", row["edit_ms"], row["frame_ms"], error,
                     sooner))
    print(f"{'renderer':<28} {'setting':<14} {'time ms':>9} {'steady ms':>10} {'rel. RMSE %':>12} "
          f"{'- noise %':>10}  sooner than Cycles at equal error")
    for renderer, setting, ms, steady, error, sooner in rows:
        steady = f"{steady:.0f}" if steady is not None else "-"
        less_noise = math.sqrt(max(error**2 - noise**2, 0.0))
        print(f"{renderer:<28} {setting:<14} {ms:>9.0f} {steady:>10} {100 * error:>12.2f} {100 * less_noise:>10.2f}  "
              f"{sooner or ''}")


def main():
    out = tempfile.mkdtemp(prefix="lightloom-cycles-")
    print(f"images in {out}")
    print(f"Cycles {bpy.app.version_string}, {THREADS} threads, {WIDTH}x{HEIGHT}, direct light only; "
          f"Lightloom: {LIGHTLOOM}")
    for name in EDIT_NAMES:
        compare(out, name)
    print("\nCycles' time includes scene sync and BVH: what an artist waits for after an edit. Lightloom's is "
          "from the edit to its frame drawn.")


main()
