local source = src{}
local m = mid{ atlas = sourse }
