local p = pair{}
mid{ atlas = p }
