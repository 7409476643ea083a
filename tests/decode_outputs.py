#!/usr/bin/env python3
"""decode_outputs.py OUT... - every texture file the main job wrote into each
OUT folder, decoded and measured here, independently of seamcook's code: the
PNG is decoded with zlib, the seams are found from asset.obj, the reference
(edges whose two faces give them different uv coordinates), and the seam energy of
Liu et al. 2017 (eq. 9: the mean over the seams' length of the squared
difference of the two sides' bilinear samples, summed over channels) is
integrated with 16 samples per texel crossed, in the space a renderer
filters the file in (linear light for sRGB colour, stored values for data).

Checked for each file:
  - the seam energy `save` reports for it (`<file>.seam_energy`) is what the
    bytes hold: within 2% (or 1e-14);
  - an 8-bit file whose erasure reported a naive-rounding floor
    (erase_seams's seam_energy_after_u8_naive for its slot) is within twice
    that floor, and the files are below their floors on average.
The folders are the main job's with obj=1 (the OBJ and texture files beside
asset.glb): every image the .glb embeds is named as its file and holds that
file's bytes, so what is measured here is what the .glb holds.
And for every normal map of asset.glb, read with the GLB's own NORMAL and
TANGENT (B = w N x T, the map decoded as 2 x - 1, the normal the renderer
reconstructs on each side of every seam, 19 points per edge, its mean gap
weighted by the edges' length):
  - each level of detail has the reference's normals wherever it has a
    vertex at the reference's position and uv (its shading and the frames
    a tangent-space map is made for are the reference's);
  - where straighten erased the map in tangent space, the reference's mean
    gap is what it reports (normal_gap_mean_after, within a quarter), and
    mip levels 0 and 1 of the map (those written: level 0 with
    mip_files=all), erased through the first level's frames,
    are at least as continuous there as the saved map and as its plain
    2 x 2 box average (renormalised) are.
Textures use repeat wrap (the main job's assets all do). Folders that do not
exist are skipped; none at all: exit status 77.
"""
import json
import math
import os
import re
import struct
import sys
import zlib

try:
    import numpy as np
except ImportError:   # setup.sh test installs python3-numpy
    print("numpy is not installed: skipped")
    sys.exit(77)


def decode_png(path):
    """8- or 16-bit grey, grey+alpha, RGB or RGBA, non-interlaced: floats in
    [0, 1], rows bottom first (row 0 is v = 0)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG")
    pos, idat, hdr = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            hdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, ctype, _, _, interlace = hdr
    if interlace or depth not in (8, 16) or ctype not in (0, 2, 4, 6):
        raise ValueError(f"{path}: PNG layout not handled here")
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[ctype]
    bpp = channels * depth // 8
    raw = zlib.decompress(idat)
    stride = w * bpp
    out = np.zeros((h, stride), dtype=np.int32)
    prev = np.zeros(stride, dtype=np.int32)
    for r in range(h):
        f = raw[r * (stride + 1)]
        line = np.frombuffer(raw, dtype=np.uint8, count=stride, offset=r * (stride + 1) + 1).astype(np.int32)
        if f == 0:
            cur = line
        elif f == 2:
            cur = (line + prev) & 255
        else:   # 1 (sub), 3 (average), 4 (Paeth) depend on the bytes left of each
            cur = np.zeros(stride, dtype=np.int32)
            for i in range(stride):
                a = cur[i - bpp] if i >= bpp else 0
                b = prev[i]
                c = prev[i - bpp] if i >= bpp else 0
                if f == 1:
                    p = a
                elif f == 3:
                    p = (a + b) // 2
                else:
                    pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                    p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                cur[i] = (line[i] + p) & 255
        out[r] = cur
        prev = cur
    if depth == 16:
        px = (out[:, 0::2] * 256 + out[:, 1::2]).astype(np.float64) / 65535.0
    else:
        px = out.astype(np.float64) / 255.0
    return px.reshape(h, w, channels)[::-1].copy()


def srgb_to_linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def read_obj(path):
    V, VT, faces, mats, mat = [], [], [], [], None
    for line in open(path):
        p = line.split()
        if not p:
            continue
        if p[0] == "v":
            V.append([float(x) for x in p[1:4]])
        elif p[0] == "vt":
            VT.append([float(x) for x in p[1:3]])
        elif p[0] == "usemtl":
            mat = p[1]
        elif p[0] == "f":
            c = [q.split("/") for q in p[1:]]
            faces.append([(int(q[0]) - 1, int(q[1]) - 1) for q in c])
            mats.append(mat)
    return np.array(V), np.array(VT), faces, mats


def seams(V, VT, faces, mats, material):
    """(length, uv a0, uv a1, uv b0, uv b1) per seam edge of the material."""
    sides = {}
    for f, m in zip(faces, mats):
        if material is not None and m != material:
            continue
        for k in range(3):
            (v0, t0), (v1, t1) = f[k], f[(k + 1) % 3]
            key = (min(v0, v1), max(v0, v1))
            uv = (tuple(VT[t0]), tuple(VT[t1])) if v0 < v1 else (tuple(VT[t1]), tuple(VT[t0]))
            sides.setdefault(key, []).append(uv)
    out = []
    for (v0, v1), s in sides.items():
        if len(s) == 2 and s[0] != s[1]:
            out.append((float(np.linalg.norm(V[v0] - V[v1])), s[0][0], s[0][1], s[1][0], s[1][1]))
    return out


def bilinear(img, u, v):
    h, w, _ = img.shape
    x, y = u * w - 0.5, v * h - 0.5
    x0, y0 = np.floor(x).astype(np.int64), np.floor(y).astype(np.int64)
    s, t = (x - x0)[:, None], (y - y0)[:, None]
    i0, i1, j0, j1 = x0 % w, (x0 + 1) % w, y0 % h, (y0 + 1) % h
    return ((1 - s) * (1 - t) * img[j0, i0] + s * (1 - t) * img[j0, i1] + (1 - s) * t * img[j1, i0] +
            s * t * img[j1, i1])


def seam_energy(img, edges):
    h, w, _ = img.shape
    total, length = 0.0, 0.0
    for le, a0, a1, b0, b1 in edges:
        a0, a1, b0, b1 = map(np.array, (a0, a1, b0, b1))
        texels = max(np.abs((a1 - a0) * (w, h)).sum(), np.abs((b1 - b0) * (w, h)).sum())
        n = int(min(200000, max(16, 16 * math.ceil(texels))))
        g = (np.arange(n) + 0.5) / n
        A = bilinear(img, a0[0] + g * (a1[0] - a0[0]), a0[1] + g * (a1[1] - a0[1]))
        B = bilinear(img, b0[0] + g * (b1[0] - b0[0]), b0[1] + g * (b1[1] - b0[1]))
        total += le * float(((A - B) ** 2).sum(axis=1).mean())
        length += le
    return total / length if length > 0 else 0.0


def read_glb(path):
    """The JSON, and an accessor reader over the binary chunk."""
    data = open(path, "rb").read()
    n = struct.unpack("<I", data[12:16])[0]
    doc = json.loads(data[20:20 + n])
    blob = data[20 + n + 8:]

    def accessor(i):
        a = doc["accessors"][i]
        view = doc["bufferViews"][a["bufferView"]]
        width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[a["type"]]
        kind = {5126: np.float32, 5125: np.uint32, 5123: np.uint16, 5121: np.uint8}[a["componentType"]]
        at = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        x = np.frombuffer(blob, dtype=kind, count=a["count"] * width, offset=at)
        x = x.astype(np.float64 if kind == np.float32 else np.int64)
        return x.reshape(-1, width) if width > 1 else x

    def image(i):
        view = doc["bufferViews"][doc["images"][i]["bufferView"]]
        at = view.get("byteOffset", 0)
        return blob[at:at + view["byteLength"]]

    return doc, accessor, image


def reconstructed_gap(P, N, T, UV, I, img):
    """Mean (over the seams' length) and largest gap between the normals
    the renderer reconstructs on the two sides of every seam edge."""
    sides = {}
    for tri in I:
        for k in range(3):
            a, b = int(tri[k]), int(tri[(k + 1) % 3])
            pa, pb = tuple(P[a]), tuple(P[b])
            sides.setdefault((min(pa, pb), max(pa, pb)), []).append((a, b) if pa < pb else (b, a))
    t = np.linspace(0.05, 0.95, 19)[:, None]

    def side(a, b):
        uv = UV[a] * (1 - t) + UV[b] * t
        m = bilinear(img, uv[:, 0], 1 - uv[:, 1])[:, :3] * 2 - 1   # glTF's v runs down
        n = N[a] * (1 - t) + N[b] * t
        tg = T[a, :3] * (1 - t) + T[b, :3] * t
        r = m[:, :1] * tg + m[:, 1:2] * T[a, 3] * np.cross(n, tg) + m[:, 2:3] * n
        return r / np.linalg.norm(r, axis=1, keepdims=True)

    total = length = largest = 0.0
    for (a0, b0), (a1, b1) in (s for s in sides.values() if len(s) == 2):
        if np.array_equal(UV[a0], UV[a1]) and np.array_equal(UV[b0], UV[b1]):
            continue
        g = np.linalg.norm(side(a0, b0) - side(a1, b1), axis=1)
        le = float(np.linalg.norm(P[a0] - P[b0]))
        total, length, largest = total + le * float(g.mean()), length + le, max(largest, float(g.max()))
    return (total / length if length > 0 else 0.0), largest


def glb_normal_checks(d, straight, failures):
    path = os.path.join(d, "asset.glb")
    if not os.path.isfile(path):
        return
    doc, accessor, image = read_glb(path)
    for mi, material in enumerate(doc.get("materials", [])):
        if "normalTexture" not in material:
            continue
        png = os.path.join(d, "glb_normal.png")
        open(png, "wb").write(image(doc["textures"][material["normalTexture"]["index"]]["source"]))
        saved = decode_png(png)
        os.remove(png)
        meshes = []
        for mesh in doc["meshes"]:
            for prim in mesh["primitives"]:
                if prim.get("material") == mi:
                    at = prim["attributes"]
                    meshes.append([accessor(at[k]) for k in ("POSITION", "NORMAL", "TANGENT", "TEXCOORD_0")] +
                                  [accessor(prim["indices"]).reshape(-1, 3)])
        if len(meshes) < 2:
            continue
        name = material.get("name", str(mi))
        gaps = [reconstructed_gap(*m, saved)[0] for m in meshes]
        print(f"{d}/asset.glb: {name}'s normal map, mean reconstructed seam gap per mesh " +
              " ".join(f"{g:.4f}" for g in gaps))
        P0, N0, _, U0, _ = meshes[0]
        where = {}   # a vertex with a hard edge through it has several
        for p, n, u in zip(P0, N0, U0):
            where.setdefault((tuple(p), tuple(u)), []).append(n)
        for k, (P, N, _, UV, _) in enumerate(meshes[1:], 1):
            same = [max(float(np.dot(n, r)) for r in where[(tuple(p), tuple(u))]) for p, n, u in zip(P, N, UV)
                    if (tuple(p), tuple(u)) in where]
            if same and min(same) < 0.9999:
                failures.append(f"{d}/asset.glb: level {k}'s normal at a reference vertex turns by "
                                f"{math.acos(max(-1.0, min(same))):.3g} rad")
        if straight.get("erase.normal.tangent_space") != 1:
            continue
        told = straight.get("erase.normal.normal_gap_mean_after")
        if told is not None and abs(gaps[0] - told) > 0.25 * told + 0.002:
            failures.append(f"{d}/asset.glb: the reference's normal map holds a mean gap of {gaps[0]:.4g}, "
                            f"straighten reports {told:.4g}")
        h, w = saved.shape[0] // 2 * 2, saved.shape[1] // 2 * 2
        box = (saved[0:h:2, 0:w:2] + saved[1:h:2, 0:w:2] + saved[0:h:2, 1:w:2] + saved[1:h:2, 1:w:2]) / 4
        v = box[:, :, :3] * 2 - 1
        box[:, :, :3] = 0.5 * (v / np.maximum(np.linalg.norm(v, axis=2, keepdims=True), 1e-12) + 1)
        plain = [gaps[1], reconstructed_gap(*meshes[1], box)[0]]   # what levels 0 and 1 would be unerased
        for level in (0, 1):
            mip = [f for f in os.listdir(os.path.join(d, "mip")) if f.endswith(f"_normal_level{level}.png")]
            for f in mip:
                g = reconstructed_gap(*meshes[1], decode_png(os.path.join(d, "mip", f)))[0]
                print(f"{d}/mip/{f}: mean reconstructed seam gap on the first level {g:.4f} "
                      f"(unerased {plain[level]:.4f})")
                if g > plain[level] + 1e-3:
                    failures.append(f"{d}/mip/{f}: the first level sees a mean gap of {g:.4g}, "
                                    f"above the unerased map's {plain[level]:.4g}")


def glb_images_are_the_files(d, failures):
    """Every image asset.glb embeds carries the name of the texture file save
    measured, and with obj=1 that file is beside it: its bytes, bit for bit."""
    glb = os.path.join(d, "asset.glb")
    if not os.path.isfile(glb):
        return
    doc, _, image = read_glb(glb)
    for i, im in enumerate(doc.get("images", [])):
        name = im.get("name")
        if not name:
            failures.append(f"{glb}: image {i} has no name")
            continue
        path = os.path.join(d, name)
        if not os.path.isfile(path):
            failures.append(f"{glb}: image {i} is {name}, which is not beside it")
        elif open(path, "rb").read() != image(i):
            failures.append(f"{glb}: image {i} differs from {name}")


def metrics_of(report, name):
    for n in report["nodes"]:
        if n.get("name") == name:
            return n.get("metrics", {})
    return {}


def main():
    folders = [d for d in sys.argv[1:] if os.path.isfile(os.path.join(d, "report.json"))]
    if not folders:
        print("no main-job output to decode: skipped")
        return 77
    failures, ratios = [], []
    for d in folders:
        report = json.load(open(os.path.join(d, "report.json")))
        # the erasure the files hold: straighten's (its erase.* metrics), which
        # erases every texture, or erase_seams's with straighten=0
        saved, erased = metrics_of(report, "save"), metrics_of(report, "erased")
        straight = metrics_of(report, "straight")
        if straight:
            erased = {k[len("erase."):]: v for k, v in straight.items() if k.startswith("erase.")}
        # the reference's mesh, which save measures the files on
        obj = os.path.join(d, "asset.obj")
        V, VT, faces, mats = read_obj(obj if os.path.isfile(obj) else os.path.join(d, "asset_lod0.obj"))
        one_material = len(set(mats)) <= 1
        for name in sorted(os.listdir(d)):
            m = re.fullmatch(r"asset_(.+)_(color|normal|emissive|occlusion|metallic_roughness)\.png", name)
            if not m:
                continue
            material, slot = m.group(1), m.group(2)
            img = decode_png(os.path.join(d, name))
            if slot in ("color", "emissive"):
                c = img.shape[2]
                colour = c if c in (1, 3) else c - 1
                img[:, :, :colour] = srgb_to_linear(img[:, :, :colour])
            edges = seams(V, VT, faces, mats, None if one_material else material)
            e = seam_energy(img, edges)
            reported = saved.get(f"{name}.seam_energy")
            line = f"{d}/{name}: {len(edges)} seams, energy {e:.4g}"
            if reported is None:
                failures.append(f"{d}/{name}: save reports no seam energy for it")
            else:
                line += f", save reports {reported:.4g}"
                if abs(e - reported) > 0.02 * reported + 1e-14:
                    failures.append(f"{d}/{name}: the bytes hold {e:.6g}, the report says {reported:.6g}")
            # the slot's own floor; the unprefixed one only when the erasure
            # erased a single texture (with several, it is their sum)
            prefixed = any(k.endswith(".seam_energy_before") for k in erased)
            key = f"{slot}.seam_energy_after_u8_naive" if prefixed else "seam_energy_after_u8_naive"
            floor = erased.get(key)
            if floor is not None and floor > 0:
                line += f", naive-rounding floor {floor:.4g} (ratio {e / floor:.3g})"
                ratios.append(e / floor)
                if e > 2 * floor:
                    failures.append(f"{d}/{name}: energy {e:.4g} above twice the naive floor {floor:.4g}")
            print(line)
        glb_images_are_the_files(d, failures)
        glb_normal_checks(d, straight, failures)
    if ratios:
        mean = sum(ratios) / len(ratios)
        print(f"mean ratio to the naive floor over {len(ratios)} files: {mean:.3g}")
        if mean >= 1:
            failures.append(f"the files are not below their naive floors on average ({mean:.3g})")
    for f in failures:
        print("FAIL", f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
