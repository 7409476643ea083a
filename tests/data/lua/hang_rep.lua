src{}
local s = string.rep("", 2^50, "")
local t = string.rep("x", 2^40)
