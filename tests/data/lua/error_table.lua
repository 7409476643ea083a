src{}
error({ code = 1 })
