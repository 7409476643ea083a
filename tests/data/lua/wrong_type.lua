local s = src{}
src{ size = "big" }
