local asset = procedural{ name = "asset", resolution = 4 }
local x = nil
local y = x.field   -- line 3: indexing nil
