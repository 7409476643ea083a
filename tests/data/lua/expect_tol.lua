local s = src{}
expect(s, "psnr", "~", 30)
