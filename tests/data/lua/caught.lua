-- The graph catches a bad --set, then makes a mistake of its own.
pcall(param, "size", 1)
src{ size = 5000 }
