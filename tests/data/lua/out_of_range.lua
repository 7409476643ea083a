src{ size = 5000 }
