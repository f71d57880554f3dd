# Plots the bench_lcd --dat files to docs/lcd_rmse.png: relative RMSE of the LCD panel against
# one-core CPU seconds for each sampling strategy, in three lightings (docs/benchmarks.md):
#   docs/bench_lcd.dat      forest.exr (sun behind the panel's plane)
#   docs/bench_lcd_sky20.dat  Preetham sky, sun at elevation 20, azimuth 180 (lights the interior)
#   docs/bench_lcd_sky60.dat  Preetham sky, sun at elevation 60, azimuth 160 (on the panel)
#   gnuplot docs/plot_lcd.gp      (from the repository root)
set terminal pngcairo size 1500,560 font "sans,10"
set output "docs/lcd_rmse.png"
set multiplot layout 1,3 title "LCD final gather: relative RMSE against one-core CPU seconds for the 400 x 300 panel"
set logscale xy
set xlabel "one-core CPU seconds (samples per texel x cost per sample)"
set ylabel "relative RMSE against a 65536-spp reference"
set grid
set key bottom left font "sans,8"
set yrange [0.001:100]
files = "docs/bench_lcd.dat docs/bench_lcd_sky20.dat docs/bench_lcd_sky60.dat"
titles = "'forest.exr' 'sky, sun 20 deg behind' 'sky, sun 60 deg behind, on the panel'"
do for [k=1:3] {
  f = word(files, k)
  set title word(titles, k)
  plot f index 0 using 2:3 with linespoints lw 2 title "BRDF", \
       f index 1 using 2:3 with linespoints lw 2 title "cosine (sun NEE)", \
       f index 3 using 2:3 with linespoints lw 2 title "BRDF+cos+window w=0.5 (default until 11-26)", \
       f index 5 using 2:3 with linespoints lw 2 title "BRDF+cos+window+env w=e=0.25 (default until 11-28)", \
       f index 9 using 2:3 with linespoints lw 3 title "BRDF+cos+env e=0.5 (default)", \
       f index 11 using 2:3 with linespoints lw 2 title "BRDF+cos+env e=0.6", \
       f index 7 using 2:3 with linespoints lw 2 title "+interior i=0.5", \
       f index 6 using 2:3 with linespoints lw 2 dt 2 title "plain cosine (no light sampling)", \
       0.01 with lines lc rgb "black" dt 3 title "1%"
}
unset multiplot
