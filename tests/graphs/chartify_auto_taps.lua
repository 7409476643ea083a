-- quad_chartify's auto on an atlas whose charts lie close together in uv:
-- the procedural asset pads its charts for 16^2 maps, so two charts' bilinear
-- taps first reach one texel at 8^2. auto keeps the atlas for 16^2 maps and
-- re-chartifies for 8^2 ones; without map_size it measures nothing of the kind.
local asset = procedural{ name = "asset", resolution = 16, texture_size = 256 }
local apart = quad_chartify{ name = "apart", atlas = asset, mode = "auto", map_size = 16 }
local close = quad_chartify{ name = "close", atlas = asset, mode = "auto", map_size = 8 }
local unmeasured = quad_chartify{ name = "unmeasured", atlas = asset, mode = "auto" }

expect(apart, "input_tap_met_texels", "==", 0)
expect(apart, "chartified", "==", 0)
expect(close, "input_tap_met_texels", ">", 0)
expect(close, "chartified", "==", 1)
expect(close, "shared_texels", "==", 0)
expect(unmeasured, "chartified", "==", 0)
