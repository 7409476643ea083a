-- Levels of detail checked against their reference, for report.html's first screen (used by test_cli).
local asset = procedural{ name = "asset", resolution = 8, texture_size = 64 }
local lods = decimate{ name = "lods", mesh = asset, ratio = {0.5, 0.1} }
local chain = share_textures{ name = "chain", lods = lods, atlas = asset }
render{ name = "check", lods = chain, reference = asset, size = 96, views = 4, modes = "textured" }
