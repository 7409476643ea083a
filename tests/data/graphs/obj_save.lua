-- Load an OBJ named on the command line and save it again.
local asset = load_atlas{ name = "load", path = param("mesh") }
save{ name = "save", atlas = asset, file = "copy" }
