local size = param("size", 64)
local ratio = param("ratio", 0.5)
local fast = param("fast", false)
local label = param("label", "plain")
src{ size = size, ratio = ratio, flag = fast, label = label }
