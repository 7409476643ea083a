local asset = procedural{ name = "asset",
  resolution = 100000 }
