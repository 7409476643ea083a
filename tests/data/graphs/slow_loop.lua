-- each pass spends about a millisecond in C for some 47,000 counted steps,
-- so the wall clock ends this long before the instruction limit would
while true do local s = string.rep("ab", 1000000) end
