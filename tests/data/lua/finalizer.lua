src{}
local keep = setmetatable({}, { __gc = function() while true do end end })
