-- A small graph that uses every part of the language.
local s = src{ size = 128, mode = "exact", name = "source" }
local m = mid{ atlas = s }
local t = two{}
local k = sink{ mesh = t.a, image = t.img }
local s2 = src{ levels = {0.25, 0.125}, flag = true, file = "some/../data/./x.obj",
                ratio = 1 }
src{ ratio = 1.0, levels = 0.5, size = 64.0 }
expect(k, "psnr", ">=", 30)
expect(m, "faces", "~", 1000, 10)
return s2
