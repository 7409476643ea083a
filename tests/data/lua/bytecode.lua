-- a binary chunk header: load must refuse it whatever mode it is asked for
local chunk = "\27Lua\84\0\25\147\r\n\26\n\4\8\8\120\86\0\0\0\0\0\0\0\0\0\0\0\40\119\64"
assert(load(chunk, "bin", "b"))
