-- The crack check can see cracks: decimation that ignores seams (seam_mode
-- "free", the MeshLab baseline) moves the two sides of a seam apart in uv, so
-- a geometry image - seam-free on the input's seams - puts them at different
-- places. The render must report it, as seam gaps and as crack pixels.
local asset = procedural{ name = "asset", resolution = 16, texture_size = 256 }
local erased = erase_seams{ name = "erased", atlas = asset }
local baked = bake_displacement{ name = "bake", atlas = erased.atlas_native, size = 256 }
local free = decimate{ name = "free", mesh = erased.atlas_native, ratio = {0.5, 0.1}, seam_mode = "free" }
local chain = share_textures{ name = "chain", lods = free, atlas = baked.atlas }
local check = render{ name = "check", lods = chain, reference = erased.atlas_native,
                      size = 128, views = 6, modes = "geometry_image" }

expect(baked, "texels_covered", ">", 0)
for k = 0, 1 do
  expect(check, "lod" .. k .. ".geometry_image.crack_pixels", ">", 0)
  expect(check, "lod" .. k .. ".geometry_image.max_seam_gap", ">", 1e-3)
  expect(check, "lod" .. k .. ".seam_energy.geometry_image", ">", 1e-6)
end
expect_image(check, "render/lod1_sheet.png", { threshold = 3, max_share = 0.002 })
