-- A list read from --set, and named nodes for --set node.param=value.
local levels = param("levels", {0.5, 0.25})
src{ name = "first", levels = levels, size = 32 }
src{ name = "second", size = param("size", 64) }
