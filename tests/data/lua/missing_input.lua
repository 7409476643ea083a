local a = src{}
mid{}
