-- the asset has no default
local asset = param("asset")
src{ file = asset }
