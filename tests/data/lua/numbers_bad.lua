src{ levels = { 0.5, "x" } }
