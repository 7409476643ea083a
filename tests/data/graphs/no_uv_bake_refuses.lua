-- bake_displacement refuses a model whose uv have no area (here none at
-- all): no texel of its maps could hold the surface. The run fails naming
-- the parameter; with the atlas quad_chartify gives it, it bakes (no_uv.lua).
local asset = load_atlas{ name = "asset", path = param("mesh") }
bake_displacement{ name = "bake", atlas = asset, size = 256 }
