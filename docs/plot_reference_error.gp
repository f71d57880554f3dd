# Plots docs/reference_error.csv (the tables of bench_reference.sh, docs/benchmarks.md) to
# docs/reference_error.png: median per-pixel error of `cave shade --view` against
# `cave reference` versus bake time, for 3/5/8 bands, without and with --split 64.
#   gnuplot docs/plot_reference_error.gp      (from the repository root)
set datafile separator ","
set terminal pngcairo size 900,560 font "sans,11"
set output "docs/reference_error.png"
set xlabel "bake time [s] (tess-2 cabin, 1024 rays, 2 bounces; 3, 5, 8 bands left to right)"
set ylabel "median per-pixel error against the reference [%]"
set yrange [0:25]
set grid
set key outside right
set title "End-to-end error (noise floor of the reference 3.5-5.9%)"
f = "docs/reference_error.csv"
sel(v, m, k) = sprintf("< awk -F, '$1==\"%s\" && $2==\"%s\" && $4==%d' %s", v, m, k, f)
L = "driver:forest driver:sunset driver:city seats:forest seats:sunset seats:city"
vw(i) = word(L, i)[1:strstrt(word(L, i), ":") - 1]
mp(i) = word(L, i)[strstrt(word(L, i), ":") + 1:]
plot for [i=1:6] sel(vw(i), mp(i), 0) using 5:7 with linespoints lw 2 lc i title word(L, i), \
     for [i=1:6] sel(vw(i), mp(i), 64) using 5:7 with linespoints dt 2 lc i \
       title word(L, i)." --split 64", \
     5 with lines lc rgb "black" dt 3 title "5% target"
