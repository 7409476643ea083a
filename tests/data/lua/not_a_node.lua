mid{ atlas = "source" }
