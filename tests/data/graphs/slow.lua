-- Big enough to take a noticeable time: for the kill -9 test.
local asset = procedural{ name = "asset", resolution = 120, texture_size = param("texture_size", 4096) }
save{ name = "save", atlas = asset, file = "big" }
