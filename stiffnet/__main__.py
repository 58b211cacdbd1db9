from stiffnet.cli import main

main()
