-- A small graph over the procedural asset: make it, save it.
local asset = procedural{
  name = "asset",
  resolution = param("resolution", 6),
  texture_size = param("texture_size", 96),
  chart_tint = param("tint", 0.08),
}
save{ name = "save", atlas = asset, file = "asset" }
