"""Blender (Cycles) side of Sequence.MotionMatchesCyclesVectorPass (tests/tracer/sequence_test.cpp):
a 20 x 20 plane at z = 0, the camera 5 above it looking down -z (Blender's default 36 mm sensor,
50 mm lens), moving from (0, 0, 5) at frame 1 to (1, 0.5, 5) at frame 2; frame 2 at 64 x 48
with the Vector pass, written as a multilayer EXR to the path after `--`.

    blender -b --python cycles_vector.py -- OUT.exr
"""
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1]
scene = bpy.context.scene
for o in list(bpy.data.objects):
    bpy.data.objects.remove(o)
scene.render.engine = "CYCLES"
scene.cycles.samples = 4
scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.render.resolution_percentage = 100
scene.render.use_motion_blur = False  # Cycles writes the Vector pass only without motion blur
bpy.ops.mesh.primitive_plane_add(size=20, location=(0, 0, 0))
cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
scene.collection.objects.link(cam)
scene.camera = cam
cam.rotation_euler = (0, 0, 0)
cam.location = (0, 0, 5)
cam.keyframe_insert("location", frame=1)
cam.location = (1.0, 0.5, 5)
cam.keyframe_insert("location", frame=2)
for fc in cam.animation_data.action.fcurves:
    for k in fc.keyframe_points:
        k.interpolation = "LINEAR"
scene.view_layers[0].use_pass_vector = True
scene.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
scene.frame_set(2)
scene.render.filepath = out
bpy.ops.render.render(write_still=True)
