src{}
src{}
error("no position", 0)
