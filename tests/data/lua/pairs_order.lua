-- pairs visits keys in a fixed order, so loops make nodes in a fixed order
local ratios = { zeta = 0.1, alpha = 0.2, [2] = 0.3, mid = 0.4, [1] = 0.5, [true] = 0.6,
                 beta = 0.7, [1.5] = 0.8 }
for k, r in pairs(ratios) do
    src{ ratio = r }
end
local seen = {}
for k in pairs({ x = 1, y = 2 }) do seen[#seen + 1] = k end
assert(seen[1] == "x" and seen[2] == "y")
-- removing entries while iterating is allowed
local t = { a = 1, b = 2, c = 3 }
for k in pairs(t) do t.b = nil end
