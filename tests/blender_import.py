# blender_import.py - run inside Blender (blender -b --python-exit-code 1
# --python tests/blender_import.py -- OUT): imports OUT/asset.glb with
# Blender's own glTF importer, as an artist's scene would, and checks it
# against the OBJ files the same save wrote, read here as plain text:
#   - one mesh object per level (lod0 the full mesh, lod<k> asset_lod<k-1>),
#     each with the OBJ's triangle count, a uv layer and the OBJ's uv extent;
#   - every material's Base Color fed by an image texture whose image has the
#     size of the PNG the MTL names.
# Debian 12's Blender 3.4 importer still uses numpy's removed alias np.bool
# (numpy 1.24): the alias is put back before the importer loads.
import os
import struct
import sys

import numpy as np

if not hasattr(np, "bool"):
    np.bool = bool

import bpy

out = sys.argv[sys.argv.index("--") + 1]
failures = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def read_obj(path):
    """triangles, uv extent (umin, vmin, umax, vmax) and the MTL it names"""
    faces, us, vs, mtl = 0, [], [], None
    with open(path) as f:
        for line in f:
            w = line.split()
            if not w:
                continue
            if w[0] == "f":
                faces += len(w) - 3
            elif w[0] == "vt":
                us.append(float(w[1]))
                vs.append(float(w[2]))
            elif w[0] == "mtllib":
                mtl = w[1]
    return faces, (min(us), min(vs), max(us), max(vs)), mtl


def png_size(path):
    with open(path, "rb") as f:
        head = f.read(24)
    return struct.unpack(">II", head[16:24])


bpy.ops.wm.read_factory_settings(use_empty=True)
bpy.ops.import_scene.gltf(filepath=os.path.join(out, "asset.glb"))
objects = {o.name: o for o in bpy.context.scene.objects if o.type == "MESH"}
levels = sorted(f for f in os.listdir(out) if f.startswith("asset_lod") and f.endswith(".obj"))
expected = ["asset.obj"] + levels
check(len(objects) == len(expected), f"{len(objects)} mesh objects, {len(expected)} levels written as OBJ")
for k, obj_file in enumerate(expected):
    o = objects.get(f"lod{k}")
    check(o is not None, f"lod{k} imported")
    if o is None:
        continue
    faces, extent, mtl = read_obj(os.path.join(out, obj_file))
    me = o.data
    check(len(me.polygons) == faces, f"lod{k}: {len(me.polygons)} faces, {obj_file} has {faces}")
    check(len(me.uv_layers) == 1, f"lod{k}: {len(me.uv_layers)} uv layer")
    if len(me.uv_layers) == 1:
        uv = np.empty(2 * len(me.loops))
        me.uv_layers[0].data.foreach_get("uv", uv)
        got = (uv[0::2].min(), uv[1::2].min(), uv[0::2].max(), uv[1::2].max())
        off = max(abs(a - b) for a, b in zip(got, extent))
        check(off < 1e-6, f"lod{k}: uv extent {tuple(round(x, 6) for x in got)}, {obj_file}'s off by {off:.2g}")
# the base colour of every material: an image of the PNG's size
mtl_maps = {}
with open(os.path.join(out, "asset.mtl")) as f:
    name = None
    for line in f:
        w = line.split()
        if len(w) >= 2 and w[0] == "newmtl":
            name = w[1]
        elif len(w) >= 2 and w[0] == "map_Kd":
            mtl_maps[name] = w[1]
for name, png in mtl_maps.items():
    mat = bpy.data.materials.get(name)
    check(mat is not None and mat.use_nodes, f"material {name} imported with nodes")
    if mat is None or not mat.use_nodes:
        continue
    bsdf = next((n for n in mat.node_tree.nodes if n.type == "BSDF_PRINCIPLED"), None)
    links = bsdf.inputs["Base Color"].links if bsdf else []
    image = links[0].from_node.image if links and links[0].from_node.type == "TEX_IMAGE" else None
    check(image is not None, f"material {name}: Base Color from an image texture")
    if image is not None:
        want = png_size(os.path.join(out, png))
        check(tuple(image.size) == want, f"material {name}: image {tuple(image.size)}, {png} is {want}")
if failures:
    raise SystemExit(f"{len(failures)} checks failed")
print("blender import: all checks passed")
