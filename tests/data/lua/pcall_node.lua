local ok, msg = pcall(src, { size = 1e9 })
assert(not ok and msg:find("outside"), msg)
local ok2 = pcall(src, { size = "x" })
assert(not ok2)
src{}
