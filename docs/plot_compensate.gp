# Plots docs/bench_compensate_full.md (bench_compensate output) to docs/compensate_speed.png:
# clipping-aware (auto, band image) and exact solves per second against patches per surface.
#   gnuplot docs/plot_compensate.gp      (from the repository root)
set terminal pngcairo size 900,540 font "sans,11"
set output "docs/compensate_speed.png"
set logscale xy
set xlabel "patches per surface (n x n)"
set ylabel "solves per second (2 cores, RGB)"
set xtics (16, 32, 64)
set grid
set key outside right
set title "Scattering compensation: speed against resolution"
data(disp, stor, solv, img) = sprintf("< awk -F'|' '$2 ~ /%s/ && $4 ~ /%s/ && $5 ~ / %s $/ && $6 ~ /%s/ {print $3, $7}' docs/bench_compensate_full.md", disp, stor, solv, img)
plot data("two-sided", "half", "auto", "band") using 1:2 with linespoints lw 2 title "two-sided wall, auto (clipping), half", \
     data("two-sided", "float", "auto", "band") using 1:2 with linespoints lw 2 title "two-sided wall, auto (clipping), float", \
     data("two-sided", "half", "exact", "smooth") using 1:2 with linespoints dt 2 title "two-sided wall, exact, half", \
     data("cave5", "half", "auto", "band") using 1:2 with linespoints lw 2 title "5-wall CAVE, auto (clipping), half", \
     data("cave5", "float", "auto", "band") using 1:2 with linespoints lw 2 title "5-wall CAVE, auto (clipping), float", \
     100 with lines lc rgb "black" dt 3 title "100/s (two-sided wall target)", \
     60 with lines lc rgb "gray" dt 3 title "60/s (CAVE target)"
