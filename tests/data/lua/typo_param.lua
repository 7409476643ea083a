src{ sise = 64 }
