-- A model without texture coordinates (tests/data/obj/blob_no_uv.obj, every
-- face's uv (0, 0)): load_atlas counts its faces, quad_chartify's auto mode
-- gives it an atlas, and the geometry image baked on that atlas holds the
-- surface, checked from its maps for cracks. Baked on the model's own uv it
-- is refused (no_uv_bake_refuses.lua).
local asset = load_atlas{ name = "asset", path = param("mesh") }
local quad = quad_chartify{ name = "chartify", atlas = asset, mode = "auto", map_size = 256 }
local bake = bake_displacement{ name = "bake", atlas = quad.atlas, size = 256 }
local mips = mipmap{ name = "mips", atlas = bake.atlas, min_size = 16 }
local check = render{ name = "check", lods = mips.levels, reference = quad.atlas, size = 128, views = 6,
                      modes = "geometry_image" }

expect(asset, "faces_without_uv", "==", 320)
expect(quad, "input_degenerate_uv_fraction", "==", 1)
expect(quad, "chartified", "==", 1)
expect(quad, "shared_texels", "==", 0)
expect(bake, "degenerate_uv_fraction", "==", 0)
expect(bake, "texels_shared", "==", 0)
-- the geometry image within 0.5% of the diagonal of the surface point of its uv
expect(bake, "geometry_image_error", "<", 0.005)
expect(check, "crack_pixels", "==", 0)
expect(check, "max_seam_gap", "<=", 1e-5)
