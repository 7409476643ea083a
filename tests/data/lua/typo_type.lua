local s = scr{}
