local s = src{}
for i = 1, 1e7 do mid{ atlas = s } end
