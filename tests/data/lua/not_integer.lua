src{
    size = 2.5,
}
