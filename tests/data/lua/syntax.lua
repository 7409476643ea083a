local s = src{}

local x = = 1
