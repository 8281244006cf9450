from kisscal.cli import main

main()
