src{ name = "a" }
src{ name = "b" }
src{ name = "a" }
