# Plots docs/bake_error.csv (written by bench_bake --csv) to docs/bake_error.png:
# direct-transfer error against rays per vertex for 2..6 SH bands.
#   gnuplot docs/plot_bake_error.gp      (from the repository root)
set datafile separator ","
set terminal pngcairo size 900,560 font "sans,11"
set output "docs/bake_error.png"
set logscale xy
set xlabel "rays per vertex (direct pass, window MIS)"
set ylabel "relative L2 error against 16384 rays [%]"
set xtics (256, 512, 1024, 2048, 4096)
set yrange [0.5:50]
set grid
set key outside right
set title "PRT direct transfer, default cabin 571K triangles (3497 vertices)"
plot for [b=2:6] "< tail -n +2 docs/bake_error.csv | sort -t, -k2,2n -k1,1n" using ($2==b ? $1 : 1/0):($5*100) with linespoints lw 2 title sprintf("%d bands, energy-weighted", b), \
     for [b=2:6] "< tail -n +2 docs/bake_error.csv | sort -t, -k2,2n -k1,1n" using ($2==b ? $1 : 1/0):($4*100) with linespoints dt 2 title sprintf("%d bands, per-vertex mean", b), \
     5 with lines lc rgb "black" dt 3 title "5% budget"
