src{}
while true do end
