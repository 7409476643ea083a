src{}
local s = string.rep("a", 40000):find(string.rep("a-", 30) .. "b")
