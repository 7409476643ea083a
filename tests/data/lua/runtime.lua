local t = nil
local n = t.x
