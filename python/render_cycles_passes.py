"""Renders a Cornell box with Blender Cycles and writes a multilayer EXR with the light passes
(DiffDir/Ind/Col, GlossDir/Ind/Col, Emit, Normal, Depth) and the denoising data, as
`denoisebench import cycles` reads it (docs/importing.md). A tool for making real inputs by hand;
no test needs Blender.

    blender -b --factory-startup -noaudio --python python/render_cycles_passes.py -- \\
        OUT.exr [--size 64x48] [--spp 64] [--seed 1] [--view-layer NAME]
"""
import argparse
import sys

import bpy


def material(name, colour, emission=None, roughness=None):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    bsdf = m.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Specular"].default_value = 0.0 if roughness is None else 0.5
    bsdf.inputs["Roughness"].default_value = 1.0 if roughness is None else roughness
    if emission:
        bsdf.inputs["Emission"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = 1.0
    return m


def quad(name, verts, mat):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
    obj = bpy.data.objects.new(name, mesh)
    obj.data.materials.append(mat)
    bpy.context.scene.collection.objects.link(obj)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    ap = argparse.ArgumentParser()
    ap.add_argument("output")
    ap.add_argument("--size", default="64x48")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--view-layer", default="ViewLayer")
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.split("x"))

    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    white = material("white", (0.73, 0.73, 0.73))
    red = material("red", (0.65, 0.05, 0.05))
    green = material("green", (0.12, 0.45, 0.15))
    glossy = material("glossy", (0.8, 0.8, 0.8), roughness=0.15)
    light = material("light", (0.0, 0.0, 0.0), emission=(17.0, 12.0, 4.0))
    quad("floor", [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], glossy)
    quad("ceiling", [(-1, -1, 2), (-1, 1, 2), (1, 1, 2), (1, -1, 2)], white)
    quad("back", [(-1, 1, 0), (1, 1, 0), (1, 1, 2), (-1, 1, 2)], white)
    quad("left", [(-1, -1, 0), (-1, 1, 0), (-1, 1, 2), (-1, -1, 2)], red)
    quad("right", [(1, -1, 0), (1, -1, 2), (1, 1, 2), (1, 1, 0)], green)
    quad("light", [(-0.25, -0.25, 1.99), (-0.25, 0.25, 1.99), (0.25, 0.25, 1.99), (0.25, -0.25, 1.99)], light)
    cam_data = bpy.data.cameras.new("camera")
    cam_data.angle = 0.69
    cam = bpy.data.objects.new("camera", cam_data)
    cam.location = (0.0, -3.9, 1.0)
    cam.rotation_euler = (1.5708, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam

    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = a.spp
    scene.cycles.seed = a.seed
    scene.cycles.use_denoising = False
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.max_bounces = 8
    scene.render.resolution_x, scene.render.resolution_y = w, h
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
    scene.view_settings.view_transform = "Standard"
    vl = scene.view_layers[0]
    vl.name = a.view_layer
    for p in ("use_pass_combined", "use_pass_z", "use_pass_normal", "use_pass_diffuse_direct",
              "use_pass_diffuse_indirect", "use_pass_diffuse_color", "use_pass_glossy_direct",
              "use_pass_glossy_indirect", "use_pass_glossy_color", "use_pass_emit"):
        setattr(vl, p, True)
    vl.cycles.denoising_store_passes = True
    scene.render.filepath = a.output
    bpy.ops.render.render(write_still=True)


main()
