-- load_atlas fails at cook time (the file does not exist), after procedural cooked.
local asset = procedural{ name = "asset", resolution = 3, texture_size = 48 }
save{ name = "save_ok", atlas = asset, file = "ok" }
local missing = load_atlas{ name = "load", path = param("mesh", "/nonexistent/missing.obj") }
save{ name = "save_bad", atlas = missing, file = "bad" }
