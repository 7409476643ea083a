-- gradient_domain in a graph, as the main job runs it with --set smooth=0.5:
-- the procedural asset's colour (tinted per chart, so its seams are wide
-- open) smoothed with half its gradients kept, seamless=false, then erased.
-- The solve narrows the seams but leaves them open (Prada et al. 2018 blur
-- seams, they do not close them); erase_seams closes them after it. With
-- seamless (the default) the node closes them itself, to the float floor.
local asset = procedural{ name = "asset", resolution = 16, texture_size = 256, chart_tint = 0.3 }
local smooth = gradient_domain{ name = "smooth", atlas = asset, operation = "smooth", gradient_scale = 0.5,
                                seamless = false }
local erased = erase_seams{ name = "erased", atlas = smooth.atlas_native }
local seamless = gradient_domain{ name = "seamless", atlas = asset, operation = "smooth", gradient_scale = 0.5 }

expect(smooth, "smooth_vcycles", "<=", 8)
expect(smooth, "smooth_residual", "<", 1e-8)
expect(smooth, "seam_energy_ratio", "<", 0.5)
expect(smooth, "seam_energy_out", ">", 1e-4)
expect(erased, "seam_energy_after", "<", 1e-12)
expect(seamless, "seam_energy_out", ">", 1e-4)
expect(seamless, "seam_energy_seamless_ratio", "<", 1e-12)
