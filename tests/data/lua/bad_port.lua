local t = two{}
local x = t.nope
