local s = src{}
mid{ s }
