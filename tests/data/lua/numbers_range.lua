src{ levels = { 0.5, 2 } }
