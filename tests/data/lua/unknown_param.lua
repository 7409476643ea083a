src{ size = 64 }
src{ zz = 1, sise = 2, aa = 3 }
