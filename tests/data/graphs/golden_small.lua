-- A small graph with a golden image and golden metrics (used by test_cli).
local asset = procedural{ name = "asset", resolution = 4, texture_size = 64,
                          chart_tint = param("tint", 0.08) }
local check = render{ name = "check", atlas = asset, size = 64, views = 1, modes = "textured", pictures = "all" }
expect(check, "crack_pixels", "==", 0)
expect_image(check, "render/lod0_textured_posx.png", { threshold = 2, max_share = 0.0 })
expect_metrics(asset)
