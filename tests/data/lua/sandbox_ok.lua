-- what the sandbox leaves out, and what it keeps
assert(getmetatable("").__index.dump == nil)
assert(string.dump == nil)
for _, name in ipairs({ "os", "io", "debug", "package", "require", "dofile", "loadfile",
                        "collectgarbage", "coroutine" }) do
    assert(rawget(_G, name) == nil, name)
end
assert(load("return 1 + 1")() == 2)
assert(load("return x", "chunk", "t", { x = 7 })() == 7)
assert(math.floor(2.5) == 2 and string.format("%d", 3) == "3" and utf8.char(72) == "H")
assert(table.concat({ "a", "b" }, ",") == "a,b")
local ok = pcall(math.randomseed)
assert(not ok)
-- constructors also work from code that load() made
local s = load("return src{ name = 'from_load' }")()
mid{ atlas = s }
src{ ratio = math.random() }
