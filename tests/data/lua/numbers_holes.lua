src{ levels = { 0.5, nil, 0.25 } }
