src{}
table.move({1}, 1, 2^40, 1, {})
