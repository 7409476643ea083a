-- lod_chain.lua: the main job. Cooks one textured asset into a chain of levels
-- of detail that all share one seam-free texture set.
--
--   seamcook run graphs/lod_chain.lua                       (the procedural asset)
--   seamcook run graphs/lod_chain.lua --set mesh=assets/cow.obj [--set texture=assets/cow.png]
--   seamcook run graphs/lod_chain.lua --set straighten=0       (keep the seams as they are)
--   seamcook run graphs/lod_chain.lua --set ratios=0.5,0.1     (two levels)
--   seamcook run graphs/lod_chain.lua --set lods.normal_turn=45 (any node's parameter, by the node's name)
--
--   seamcook run graphs/lod_chain.lua --set chartify=always   (auto|always|never: a quad atlas first)
--   seamcook run graphs/lod_chain.lua --set smooth=0.5        (colour smoothed first; 2: sharpened)
--   seamcook run graphs/lod_chain.lua --set erased_exr=1      (the float erasure as EXR files too)
--   seamcook run graphs/lod_chain.lua --set obj=1             (OBJ/MTL and texture files beside asset.glb)
--   seamcook run graphs/lod_chain.lua --set mip_files=all     (every mip level, displacement maps too)
--
-- load -> quad_chartify -> [gradient_domain] -> straighten (erasing) or erase_seams -> decimate (seam-aware)
--      -> share_textures -> save, render (crack check)
--      -> bake_displacement (geometry image, displacement per LOD) -> mipmap -> render (every LOD x mip)
local mesh = param("mesh", "")
local asset
if mesh == "" then
  asset = procedural{
    name = "asset",
    resolution = param("resolution", 24),
    texture_size = param("texture_size", 512),
  }
else
  asset = load_atlas{ name = "asset", path = mesh, texture = param("texture", ""),
                      slots = param("slots", "all") }
end

-- A new atlas when the input's cannot serve the chain (Purnomo et al. 2004):
-- auto re-chartifies when its uv share texels (mirrored or overlapping
-- charts), are missing, hold more charts than decimation can collapse, or
-- come within a texel of each other on the maps baked below (bake_size: one
-- texel would hold two parts of the surface, so the maps' seams land off
-- it); always / never force it. The quad atlas is seam-free by construction
-- and its chart borders are straight, so the nodes below keep working on it.
local ratios = param("ratios", {0.5, 0.1, 0.01})   -- --set ratios=0.5,0.1
local min_ratio = 1
for _, r in ipairs(ratios) do min_ratio = math.min(min_ratio, r) end
local bake_size = param("bake_size", 1024)
local chartified = quad_chartify{ name = "chartify", atlas = asset, mode = param("chartify", "auto"),
                                  texture_size = param("chart_texture_size", 0), min_ratio = min_ratio,
                                  map_size = bake_size }
asset = chartified.atlas

-- Gradient-domain filtering (Prada et al. 2018), off by default: smooth=BETA
-- scales the gradients of one texture (smooth_texture, colour by default):
-- 0 <= BETA < 1 smooths, BETA > 1 sharpens, held to the input by
-- smooth_screening (the paper's 1e4 on a surface of unit area). It runs
-- before the erasure: the filter blurs the seams but does not close them,
-- and straighten (or erase_seams) closes them next, so the node's own
-- erasure is off (seamless = false).
local smooth = param("smooth", -1)
if smooth >= 0 then
  asset = gradient_domain{ name = "smooth", atlas = asset, operation = smooth > 1 and "sharpen" or "smooth",
                           gradient_scale = smooth, screening = param("smooth_screening", 1e4),
                           texture = param("smooth_texture", "color"), seamless = false }.atlas_native
end

-- Seam-free textures (Liu §4), in the input's own format: an 8-bit input
-- stays 8-bit, optimally rounded, so what is checked is what is written.
-- filter_space: sRGB colour is erased, straightened and mip-mapped in linear
-- light, the way GPUs filter sRGB textures (glTF, GL/Vulkan sRGB formats);
-- encoded works on the stored values, for engines that filter those.
-- preset: the erasure's weights (local keeps interior texels; global favours
-- gradients).
local filter_space = param("filter_space", "linear")
local preset = param("preset", "local")
-- save measures every texture file it writes, decoded as a renderer filters
-- it, and fails when the file's seams open wider than the image's by more
-- than max_file_seam_gap (a lossy format or a conversion).
local max_file_seam_gap = param("max_file_seam_gap", 1e-6)
-- erased_exr=1: also the float erasure of the input's own uv as EXR files
-- (asset_erased_*); off by default, as --out holds the assets.
if param("erased_exr", 0) ~= 0 then
  local erased = erase_seams{ name = "erased", atlas = asset, preset = preset, filter_space = filter_space }
  save{ name = "save_erased_exr", atlas = erased.atlas, file = "asset_erased", format = "exr", glb = false,
        max_seam_gap = max_file_seam_gap }
end

-- Straight, evenly parameterised seams (Liu §6), so decimation can collapse
-- them: straighten re-renders the textures into the new uv and erases every
-- texture's seams, moved or not, so no erase_seams runs before it.
-- straighten=0 keeps the input's uv and only erases.
local shared
if param("straighten", 1) ~= 0 then
  shared = straighten{ name = "straight", atlas = asset,
                       tolerance = param("straighten_tolerance", 0.01),
                       filter_space = filter_space, preset = preset }.atlas_native
else
  shared = erase_seams{ name = "erased", atlas = asset, preset = preset, filter_space = filter_space }.atlas_native
end

-- Levels of detail from the mesh alone: new texture bytes never re-decimate.
-- max_error: no collapse may leave a level farther than this from the input
-- (a fraction of the bounding-box diagonal); a level that cannot reach its
-- face target without that stops short (blocked_max_error) instead of
-- flattening what its seams leave collapsible (BoomBox at 10%: 1,016 faces
-- 8.7% off unbounded, 1,113 faces 1.9% off with 0.02). 0: no bound.
-- map_size: decimate for displacement maps of that size (bake_size, say):
-- collapses cost more where a texel spans much of the surface (squeezed
-- charts), and none makes a uv sliver, moves a uv silhouette more than
-- 5e-4 of the diagonal or leaves a crease too sharp for the map's texels:
-- what a seam-free map cannot bring back (BoomBox, level 0.1 at 1024^2:
-- displaced within 8.9e-4 of the diagonal instead of 1.7e-2, at 1,170
-- faces instead of 886). 0: off.
-- contact_distance: an open part's rim within this fraction of the diagonal
-- of another part (a seed's rim in a cut fruit, a sleeve on a body) gets no
-- farther from that part, nor higher over it, at its vertices and along its
-- edges (lods.contact_slack: but for this fraction of the diagonal): decimated
-- apart, the two open a gap that shows the open part's inside (Avocado,
-- WaterBottle and BoomBox show such back faces at their 10% level without
-- it). Assets of many nested parts stop higher (MuruCat: 2,125 faces instead
-- of 1,352). 0: off.
local lods = decimate{ name = "lods", mesh = shared,
                       ratio = ratios,
                       max_error = param("max_error", 0.02),
                       map_size = param("map_size", 0),
                       contact_distance = param("contact_distance", 0.01) }
local chain = share_textures{ name = "chain", lods = lods, atlas = shared }
-- save writes one asset.glb (glTF 2.0) holding the full mesh and every level
-- (MSFT_lod) with the textures embedded; obj=1 adds OBJ/MTL per level and the
-- texture files they name (the same bytes as the .glb's images).
save{ name = "save", atlas = shared, lods = chain, file = param("file", "asset"), max_seam_gap = max_file_seam_gap,
      obj = param("obj", 0) ~= 0 }

-- The crack check: every level, rendered the way a GPU samples the shared
-- textures; a crack pixel or a seam gap fails the cook, naming level, mode, view.
-- pictures: a contact sheet per level and the views that fail; all: every view.
local pictures = param("pictures", "sheets")
render{ name = "check", lods = chain, reference = shared,
        size = param("render_size", 512), modes = "textured", pictures = pictures,
        max_crack_pixels = param("max_crack_pixels", 0),
        max_seam_gap = param("max_seam_gap", 1e-6) }

-- Geometry from maps (Liu §7): a geometry image shared by every level and a
-- vector displacement map per level, seam-free; then seam-free mip chains of
-- every map (§9), and the same crack check on every LOD at every mip level,
-- with positions fetched from the maps and tessellated.
local baked = bake_displacement{ name = "bake", atlas = shared, lods = chain,
                                 size = bake_size }
-- mip_min: the chains stop once the largest texture is at most mip_min^2
-- (a smaller map's chain stops as many levels down). Geometry fetched from a
-- level stays fold-free while the gutters between charts span 2 texels or
-- more there: the procedural asset pads its charts for 16^2; the corpus's
-- maps fold sooner, which the map check reports (fold_pixels) and does not
-- fail on unless max_map_fold_pixels is set.
-- erase_min_size: mip levels with both sides below it are averaged, not
-- erased (an atlas of thousands of charts, pizza's, cannot be erased once its
-- charts fall under a texel: --set erase_min_size=2048 there). Levels left
-- unerased keep their seams, and check_maps's seam-gap limit says so.
-- mip_files: which chains become files in mip/: textures (the default: the
-- texture set's levels 1 and down, level 0 being the .glb's texture); all
-- (every level of every chain, with the geometry image and each level's
-- displacement map as mip-mapped EXR files); none.
local mip_files = param("mip_files", "textures")
local mips = mipmap{ name = "mips", lods = baked.lods, min_size = param("mip_min", 16),
                     erase_min_size = param("erase_min_size", 1), filter_space = filter_space,
                     files = mip_files, files_from_level = mip_files == "all" and 0 or 1 }
-- Its levels have the uv of the textured check's, whose uv pictures are in
-- render/: with pictures=all it also draws that uv over each mip level.
render{ name = "check_maps", lods = mips.levels, reference = shared, folder = "render_maps", pictures = pictures,
        uv_pictures = pictures == "all", size = param("map_render_size", 256), views = param("map_views", 6),
        modes = "geometry_image,displaced,tessellated",
        max_crack_pixels = param("max_crack_pixels", 0),
        max_seam_gap = param("max_map_seam_gap", 1e-5) }
