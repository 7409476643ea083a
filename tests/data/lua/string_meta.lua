local dump = ("x").dump
dump(function() end)
