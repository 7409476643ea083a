-- lod_chain.lua: the main job. Cooks one textured asset into what every level
-- of detail shares.
--
--   seamcook run graphs/lod_chain.lua                       (the procedural asset)
--   seamcook run graphs/lod_chain.lua --set mesh=assets/cow.obj [--set texture=assets/cow.png]
--
-- With no mesh, the asset is the procedural one, so the graph runs anywhere.
local mesh = param("mesh", "")
local asset
if mesh == "" then
  asset = procedural{
    name = "asset",
    resolution = param("resolution", 24),
    texture_size = param("texture_size", 512),
  }
else
  asset = load_atlas{ name = "asset", path = mesh, texture = param("texture", "") }
end

save{ name = "save_input", atlas = asset, file = param("file", "asset") }
