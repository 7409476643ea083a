-- The procedural asset erased, and saved from the 8-bit atlas; float=1 also
-- saves the float atlas (as EXR), an output the first graph does not read.
local asset = procedural{ name = "asset", resolution = 6, texture_size = 64 }
local erased = erase_seams{ name = "erased", atlas = asset }
if param("float", 0) ~= 0 then
  save{ name = "save_float", atlas = erased.atlas, file = "float", format = "exr" }
end
save{ name = "save", atlas = erased.atlas_native, file = "native" }
