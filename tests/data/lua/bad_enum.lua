src{ mode = "fastest" }
