"""lightmap_roundtrip.py: runs inside Blender (blender -b --python THIS -- ARGS).

Imports gi-bake's lightmap glTF, applies the lightmap EXR to every mesh
through the second UV set (TEXCOORD_1) as an emission shader of strength 1,
so a surface shows albedo x irradiance / pi, renders the camera gi-bake
--render used with Cycles (no bounces: the light is all in the texture),
and writes a linear single-layer EXR.
ARGS: GLB EXR OUT.exr EYE(x,y,z) TARGET(x,y,z) FOV_DEG W H, in the scene's
Y-up frame (glTF's); Blender's importer turns Y-up into Z-up."""
import math
import sys

import bpy
import mathutils


def to_blender(p):
    x, y, z = p
    return mathutils.Vector((x, -z, y))


def lightmap_material(img, uv_name):
    mat = bpy.data.materials.new("gi-lightmap")
    mat.use_nodes = True
    nt = mat.node_tree
    nt.nodes.clear()
    uv = nt.nodes.new("ShaderNodeUVMap")
    uv.uv_map = uv_name
    tex = nt.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.interpolation = "Linear"
    # A layered EXR loads as MULTILAYER; R,G,B (no prefix) is its first pass, "Combined".
    if img.type == "MULTILAYER":
        tex.image_user.multilayer_layer = 0
        tex.image_user.multilayer_pass = 0
    em = nt.nodes.new("ShaderNodeEmission")
    em.inputs["Strength"].default_value = 1.0
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(uv.outputs["UV"], tex.inputs["Vector"])
    nt.links.new(tex.outputs["Color"], em.inputs["Color"])
    nt.links.new(em.outputs["Emission"], out.inputs["Surface"])
    return mat


def main():
    argv = sys.argv[sys.argv.index("--") + 1:]
    glb, exr, out = argv[0], argv[1], argv[2]
    eye = [float(v) for v in argv[3].split(",")]
    target = [float(v) for v in argv[4].split(",")]
    fov, w, h = float(argv[5]), int(argv[6]), int(argv[7])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=glb)
    img = bpy.data.images.load(exr)
    meshes = 0
    for ob in list(bpy.context.scene.objects):
        if ob.type != "MESH":
            continue
        uvs = ob.data.uv_layers
        if len(uvs) < 2:
            print("FAIL: mesh %s has %d UV sets, expected 2" % (ob.name, len(uvs)))
            sys.exit(1)
        ob.data.materials.clear()
        ob.data.materials.append(lightmap_material(img, uvs[1].name))
        meshes += 1
    print("blender: %d mesh(es) with the lightmap on UV set 2" % meshes)
    scene = bpy.context.scene
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.data.sensor_fit = "VERTICAL" if w >= h else "HORIZONTAL"
    cam.data.angle = math.radians(fov)
    e, t = to_blender(eye), to_blender(target)
    cam.location = e
    cam.rotation_euler = (t - e).to_track_quat("-Z", "Y").to_euler()
    r = scene.render
    r.engine = "CYCLES"
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise
    scene.cycles.max_bounces = 0
    scene.cycles.filter_width = 0.01    # the cone-traced view takes pixel centres
    scene.view_settings.view_transform = "Standard"
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    r.image_settings.exr_codec = "ZIP"
    r.filepath = out
    bpy.ops.render.render(write_still=True)


main()
