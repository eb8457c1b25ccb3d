set terminal pngcairo size 1100,620 font 'sans,10'
set output 'ms_per_step.png'
set datafile separator ','
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.85 border -1
set logscale y
set ylabel 'wall time per 0.01 s step [ms]'
set title 'Time per step (median of repeated runs)'
set key outside right top font ',9'
set xtics rotate by -20
set grid ytics
plot for [i=2:6] 'ms_per_step.csv' using i:xtic(1) title columnhead(i)
