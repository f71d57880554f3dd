# Plots docs/bench_compensate_full.md (bench_compensate output) to docs/compensate_speed.png:
# clipping-aware (auto, band image) solves per second against patches per surface, for each
# storage of K (float, half, block low-rank).
#   gnuplot docs/plot_compensate.gp      (from the repository root)
set terminal pngcairo size 960,560 font "sans,11"
set output "docs/compensate_speed.png"
set logscale xy
set xlabel "patches per surface (n x n)"
set ylabel "clipping-aware solves per second (2 cores, RGB)"
set xtics (16, 32, 64, 128)
set grid
set key outside right
set title "Scattering compensation: speed against resolution"
data(disp, stor, solv, img) = sprintf("< awk -F'|' '$2 ~ /%s/ && $4 ~ / %s / && $5 ~ / %s $/ && $6 ~ /%s/ && $7 ~ /[0-9]/ {print $3, $7}' docs/bench_compensate_full.md", disp, stor, solv, img)
plot data("two-sided", "low-rank", "auto", "band") using 1:2 with linespoints lw 2 title "two-sided wall, low-rank", \
     data("two-sided", "half", "auto", "band") using 1:2 with linespoints lw 2 title "two-sided wall, half", \
     data("two-sided", "float", "auto", "band") using 1:2 with linespoints lw 2 title "two-sided wall, float", \
     data("cave5", "low-rank", "auto", "band") using 1:2 with linespoints lw 2 dt 2 title "5-wall CAVE, low-rank", \
     data("cave5", "half", "auto", "band") using 1:2 with linespoints lw 2 dt 2 title "5-wall CAVE, half", \
     data("cave5", "float", "auto", "band") using 1:2 with linespoints lw 2 dt 2 title "5-wall CAVE, float", \
     100 with lines lc rgb "black" dt 3 title "100/s (two-sided wall target)", \
     60 with lines lc rgb "gray" dt 3 title "60/s (CAVE target)"
