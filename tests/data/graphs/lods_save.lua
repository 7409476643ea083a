-- The procedural asset decimated into levels of detail and saved, a file per level.
local asset = procedural{ name = "asset", resolution = param("resolution", 8), texture_size = 64 }
local lods = decimate{ name = "lods", mesh = asset, ratio = param("ratios", {0.5, 0.25, 0.1}),
                       hausdorff_samples = 0 }
local chain = share_textures{ name = "chain", lods = lods, atlas = asset }
save{ name = "save", atlas = asset, lods = chain, file = "asset" }
