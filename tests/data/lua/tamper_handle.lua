local s = src{}
assert(getmetatable(s) == false)
local ok = pcall(setmetatable, s, {})
assert(not ok)
s.atlas = 1
