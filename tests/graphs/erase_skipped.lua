-- expect failure: expectation failed: check\.lod[0-9]\.seam_energy\.color = [0-9.e-]+, expected < 1e-06
--
-- The main job without erase_seams: the colour seams stay, the textured
-- pictures show them, and the seam-energy bound the main job keeps catches
-- it (this test passes when that expectation fails, as the line above says).
local asset = procedural{ name = "asset", resolution = 16, texture_size = 256, chart_tint = 0.3 }
local lods = decimate{ name = "lods", mesh = asset, ratio = {0.5, 0.1} }
local chain = share_textures{ name = "chain", lods = lods, atlas = asset }
local check = render{ name = "check", lods = chain, reference = asset, size = 192, views = 7, modes = "textured",
                      pictures = "all" }

for k = 0, 1 do
  expect(check, "lod" .. k .. ".textured.crack_pixels", "==", 0)  -- no cracks: the seams are in colour only
  expect(check, "lod" .. k .. ".seam_gap.color", ">", 0.05)
  expect(check, "lod" .. k .. ".seam_energy.color", "<", 1e-6)     -- the bound the main job keeps: fails here
end
expect_image(check, "render/lod0_textured_obl0.png", { threshold = 3, max_share = 0.002 })
