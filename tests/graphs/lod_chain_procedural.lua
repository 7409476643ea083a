-- The main job on the procedural asset, with what must hold at every level:
-- seams erased, targets reached, uv never flipped, no crack pixel, no seam gap.
local asset = procedural{ name = "asset", resolution = 16, texture_size = 256 }
local erased = erase_seams{ name = "erased", atlas = asset }
local lods = decimate{ name = "lods", mesh = erased.atlas_native, ratio = {0.5, 0.1, 0.02} }
local chain = share_textures{ name = "chain", lods = lods, atlas = erased.atlas_native }
local check = render{ name = "check", lods = chain, reference = erased.atlas_native,
                      size = 128, views = 6, modes = "textured", pictures = "all" }

expect(erased, "seam_energy_before", ">", 1e-4)          -- the asset has real seams
expect(erased, "seam_energy_after", "<", 1e-12)
expect(erased, "max_seam_gap_after", "<", 1e-6)

-- faces within 1% of each target (3072 input faces)
expect(lods, "lod0.faces", "~", 1536, 16)
expect(lods, "lod1.faces", "~", 307, 4)
expect(lods, "lod2.faces", "~", 61, 1)
for k = 0, 2 do
  expect(lods, "lod" .. k .. ".flipped_uv_faces", "==", 0)
  expect(check, "lod" .. k .. ".textured.crack_pixels", "==", 0)
  expect(check, "lod" .. k .. ".textured.max_seam_gap", "<=", 1e-6)
end
expect(check, "crack_pixels", "==", 0)

-- Geometry from maps: the geometry image and each level's displacement map,
-- in every mode, tessellated too; no crack pixel, no seam gap over 1e-6.
local baked = bake_displacement{ name = "bake", atlas = erased.atlas_native, lods = chain, size = 256 }
local maps = render{ name = "maps", lods = baked.lods, reference = erased.atlas_native, folder = "maps",
                     size = 128, views = 6, modes = "geometry_image,displaced,tessellated" }
for k = 0, 2 do
  for _, mode in ipairs({ "geometry_image", "displaced", "tessellated" }) do
    expect(maps, "lod" .. k .. "." .. mode .. ".crack_pixels", "==", 0)
    expect(maps, "lod" .. k .. "." .. mode .. ".max_seam_gap", "<=", 1e-6)
  end
  expect(maps, "lod" .. k .. ".seam_energy.geometry_image", "<", 1e-8)
  expect(maps, "lod" .. k .. ".seam_energy.displacement", "<", 1e-8)
  expect(baked, "lod" .. k .. ".reconstruction_error", "<", 1e-2)
end
expect_image(maps, "maps/lod2_sheet.png", { threshold = 3, max_share = 0.002 })

-- the files as written: the 8-bit PNG, decoded and filtered in linear light,
-- keeps the seams the erasure left (its optimal rounding: far under the
-- naive rounding's energy), and adds nothing to them
local saved = save{ name = "save", atlas = erased.atlas_native, lods = chain, max_seam_gap = 1e-6 }
expect(erased, "seam_energy_after_u8_naive", ">", 1e-6)
expect(saved, "asset_default_color.png.seam_gap_added", "==", 0)
expect(saved, "asset_default_color.png.seam_energy", "<", 1e-7)

-- what it looks like, and every decimation metric, against goldens
expect_image(check, "render/lod1_textured_posx.png", { threshold = 3, max_share = 0.002 })
expect_metrics(lods, { tolerance = 1e-6 })
