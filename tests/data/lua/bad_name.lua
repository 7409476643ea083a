src{ name = "has space" }
