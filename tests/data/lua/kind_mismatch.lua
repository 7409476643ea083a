local t = two{}
mid{ atlas = t.img }
