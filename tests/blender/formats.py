"""formats.py OUTDIR: one Blender scene written to glTF, FBX, Collada and OBJ.

Run by formats.sh inside Blender (blender -b --python formats.py -- OUTDIR).
The scene holds what the formats carry differently: a sun, a 500 W point
lamp, a 800 W spot lamp of blend 0.3, a one-sided emitter of strength 1 and
its mirror image (scale -1), a linked duplicate (one mesh, two objects), a
textured floor, and Principled materials of roughness 0.2 and 0.8. Writes
OUTDIR/scene.{glb,fbx,dae} with the lamps and OUTDIR/plain.{glb,obj}
without them (OBJ carries none)."""
import math
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1]
bpy.ops.wm.read_factory_settings(use_empty=True)


def material(name, color, rough, emit=None):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = color
    p.inputs["Roughness"].default_value = rough
    if emit:
        p.inputs["Emission"].default_value = emit
        p.inputs["Emission Strength"].default_value = 1.0
    return m


# A 4 x 4 checker texture, written beside the exports (FBX and OBJ refer to it).
img = bpy.data.images.new("checker", 4, 4)
img.pixels = [v for y in range(4) for x in range(4)
              for v in ((0.8, 0.3, 0.1, 1) if (x + y) % 2 else (0.2, 0.4, 0.7, 1))]
img.filepath_raw = out + "/checker.png"
img.file_format = "PNG"
img.save()

bpy.ops.mesh.primitive_plane_add(size=16, location=(0, 0, 0))
floor = material("floor", (1, 1, 1, 1), 0.8)
tex = floor.node_tree.nodes.new("ShaderNodeTexImage")
tex.image = bpy.data.images.load(out + "/checker.png")
floor.node_tree.links.new(tex.outputs["Color"], floor.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
bpy.context.object.data.materials.append(floor)

bpy.ops.mesh.primitive_cube_add(size=1.5, location=(2, 2, 0.75))
bpy.context.object.data.materials.append(material("shiny", (0.6, 0.5, 0.4, 1), 0.2))
twin = bpy.context.object.copy()  # a linked duplicate: the same mesh under a second object
twin.location = (-2.5, 2, 0.75)
bpy.context.collection.objects.link(twin)

# A one-sided emitter facing down, and its mirror image (scale -1 in x).
glow = material("glow", (0.5, 0.5, 0.5, 1), 0.8, emit=(1.0, 0.9, 0.8, 1))
for x, sx in ((-3.0, 1), (3.0, -1)):
    bpy.ops.mesh.primitive_plane_add(size=1, location=(x, -3, 1.5), rotation=(math.pi, 0, 0))
    bpy.context.object.scale = (sx, 1, 1)
    bpy.context.object.data.materials.append(glow)

bpy.ops.export_scene.gltf(filepath=out + "/plain.glb")
bpy.ops.export_scene.obj(filepath=out + "/plain.obj")

bpy.ops.object.light_add(type="SUN", location=(0, 0, 10), rotation=(0.5, 0.3, 0.2))
bpy.context.object.data.energy = 3
bpy.ops.object.light_add(type="POINT", location=(0, 0, 2.5))
bpy.context.object.data.energy = 500
bpy.context.object.data.shadow_soft_size = 0
bpy.ops.object.light_add(type="SPOT", location=(-3, 3, 3), rotation=(0.3, 0, 0))
spot = bpy.context.object.data
spot.energy, spot.spot_size, spot.spot_blend, spot.shadow_soft_size = 800, math.radians(60), 0.3, 0

bpy.ops.export_scene.gltf(filepath=out + "/scene.glb", export_lights=True)
bpy.ops.export_scene.fbx(filepath=out + "/scene.fbx", path_mode="COPY", embed_textures=True)
bpy.ops.wm.collada_export(filepath=out + "/scene.dae")
print("formats: wrote", out)
