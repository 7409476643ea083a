setmetatable(_G, nil)
local s = src{}
local make_mid, ex = mid, expect
setmetatable(_G, {
    __index = function(_, k) error("no global " .. k) end,
    __newindex = function() error("globals are read-only") end,
})
rawset(_G, "src", nil)
rawset(_G, "param", nil)
string.rep = nil
local m = make_mid{ atlas = s }
ex(m, "faces", "<", 10)
