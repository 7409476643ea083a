-- A quad atlas of the procedural asset, forced (mode always): every mip level
-- it outputs rendered the way a GPU samples it (plain bilinear at that
-- level's uv), and checked for seams without any erase step; then the chain
-- on it: decimation keeps the atlas seam-free at every level of detail.
local asset = procedural{ name = "asset", resolution = 16, texture_size = 256 }
local quad = quad_chartify{ name = "quad", atlas = asset, mode = "always", texture_size = 256,
                            target_quads = 24, min_size = 32 }
local levels = render{ name = "levels", lods = quad.levels, reference = quad.atlas, folder = "levels",
                       size = 128, views = 6, modes = "textured" }

expect(quad, "chartified", "==", 1)
expect(quad, "flipped_triangles", "==", 0)
expect(quad, "boundary_mismatch", "==", 0)
expect(quad, "shared_texels", "==", 0)
expect(quad, "levels", ">=", 3)
for k = 0, 2 do
  expect(levels, "lod" .. k .. ".seam_energy.color", "<=", 1e-14)
  expect(levels, "lod" .. k .. ".textured.max_seam_gap", "<=", 1e-6)
  expect(levels, "lod" .. k .. ".textured.crack_pixels", "==", 0)
end

local lods = decimate{ name = "lods", mesh = quad.atlas, ratio = {0.5, 0.2} }
local chain = share_textures{ name = "chain", lods = lods, atlas = quad.atlas }
local check = render{ name = "check", lods = chain, reference = quad.atlas, size = 128, views = 6, modes = "textured" }
for k = 0, 1 do
  expect(lods, "lod" .. k .. ".flipped_uv_faces", "==", 0)
  expect(check, "lod" .. k .. ".seam_energy.color", "<=", 1e-14)
  expect(check, "lod" .. k .. ".textured.crack_pixels", "==", 0)
end
