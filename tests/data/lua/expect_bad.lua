local s = src{}
expect(s, "psnr", ">=", 30)
expect(s, "psnr", "!=", 30)
