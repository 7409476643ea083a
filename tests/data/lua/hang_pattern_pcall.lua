src{}
local ok = pcall(function() return string.rep("a", 40000):match(string.rep("a-", 30) .. "b") end)
while true do end
